// Test and bench meshes made without CGAL: geodesic spheres (an icosahedron with every face cut into
// frequency^2 triangles, 20 * frequency^2 in all) mapped onto an ellipsoid or a bumpy sphere, and plain
// writers for binary STL and OBJ, so the readers under test decode files other code wrote.
#pragma once

#include "tests/temp_dir.hpp"

#include <Eigen/Core>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace rodfab::testing {

// A file of the meshing tests' own scratch folder (tests/temp_dir.hpp), and text written to a file as it is.
inline std::filesystem::path scratch(const std::string& name) { return rodfab::test::processScratch("meshing", name); }
inline void writeText(const std::filesystem::path& file, const std::string& text) { std::ofstream(file, std::ios::binary) << text; }

struct SimpleMesh {
  std::vector<Eigen::Vector3d> points;
  std::vector<std::array<std::uint32_t, 3>> triangles;  // counter-clockwise seen from outside
};

// Unit-sphere geodesic mesh of 20 * frequency^2 triangles; `map` moves each unit-sphere point.
inline SimpleMesh geodesicSphere(int frequency, const std::function<Eigen::Vector3d(const Eigen::Vector3d&)>& map) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  const std::array<Eigen::Vector3d, 12> corner = {{{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                                                   {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}}};
  const int faces[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                            {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                            {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  SimpleMesh mesh;
  // A point is keyed by its corner weights in corner order, so points on shared edges are computed
  // once, by the same arithmetic, whichever face reaches them.
  std::map<std::array<int, 24>, std::uint32_t> index;
  auto vertex = [&](const int c[3], int i, int j) {
    std::array<int, 24> key{};
    const int w[3] = {frequency - i - j, i, j};
    for (int k = 0; k < 3; ++k) key[2 * c[k]] = w[k];
    auto [it, fresh] = index.try_emplace(key, static_cast<std::uint32_t>(mesh.points.size()));
    if (fresh) {
      Eigen::Vector3d p = Eigen::Vector3d::Zero();
      for (int k = 0; k < 12; ++k) p += corner[k] * key[2 * k];
      mesh.points.push_back(map(p.normalized()));
    }
    return it->second;
  };
  for (const auto& f : faces)
    for (int i = 0; i < frequency; ++i)
      for (int j = 0; i + j < frequency; ++j) {
        mesh.triangles.push_back({vertex(f, i, j), vertex(f, i + 1, j), vertex(f, i, j + 1)});
        if (i + j + 1 < frequency) mesh.triangles.push_back({vertex(f, i + 1, j), vertex(f, i + 1, j + 1), vertex(f, i, j + 1)});
      }
  return mesh;
}

inline SimpleMesh ellipsoid(int frequency, double a, double b, double c) {
  return geodesicSphere(frequency, [=](const Eigen::Vector3d& p) { return Eigen::Vector3d(a * p.x(), b * p.y(), c * p.z()); });
}

// Radius r * (1 + 0.08 sin(6x) sin(5y) sin(4z)) on the unit sphere's point (x, y, z).
inline SimpleMesh bumpySphere(int frequency, double r) {
  return geodesicSphere(frequency, [=](const Eigen::Vector3d& p) {
    return Eigen::Vector3d(p * r * (1 + 0.08 * std::sin(6 * p.x()) * std::sin(5 * p.y()) * std::sin(4 * p.z())));
  });
}

// Coordinates rounded to float, as STL stores them, so an OBJ of the same mesh holds the same numbers.
// (The volatile is needed: GCC 12 -O2 drops the double -> float -> double round trip on Eigen vectors
// held in a std::vector, both with static_cast per coefficient and with .cast<float>().cast<double>().)
inline void roundToFloat(SimpleMesh& mesh) {
  for (auto& p : mesh.points)
    for (int k = 0; k < 3; ++k) {
      volatile float f = static_cast<float>(p[k]);
      p[k] = f;
    }
}

inline void writeBinaryStl(const SimpleMesh& mesh, const std::string& file) {
  std::ofstream out(file, std::ios::binary);
  char header[80] = "binary STL written by rodfab's tests";
  out.write(header, 80);
  const std::uint32_t n = static_cast<std::uint32_t>(mesh.triangles.size());
  out.write(reinterpret_cast<const char*>(&n), 4);
  for (const auto& t : mesh.triangles) {
    float v[12] = {0, 0, 0};
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a) v[3 + 3 * k + a] = static_cast<float>(mesh.points[t[k]][a]);
    out.write(reinterpret_cast<const char*>(v), sizeof v);
    const std::uint16_t attribute = 0;
    out.write(reinterpret_cast<const char*>(&attribute), 2);
  }
}

inline void writeAsciiStl(const SimpleMesh& mesh, const std::string& file) {
  std::ofstream out(file);
  out.precision(17);  // the float's value exactly, so a double reader gets the float back
  out << "solid test\n";
  for (const auto& t : mesh.triangles) {
    out << "facet normal 0 0 0\nouter loop\n";
    for (int k = 0; k < 3; ++k)
      out << "vertex " << double(static_cast<float>(mesh.points[t[k]].x())) << ' '
          << double(static_cast<float>(mesh.points[t[k]].y())) << ' ' << double(static_cast<float>(mesh.points[t[k]].z())) << '\n';
    out << "endloop\nendfacet\n";
  }
  out << "endsolid test\n";
}

inline void writeObj(const SimpleMesh& mesh, const std::string& file) {
  std::ofstream out(file);
  out.precision(17);
  for (const auto& p : mesh.points) out << "v " << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  for (const auto& t : mesh.triangles) out << "f " << t[0] + 1 << ' ' << t[1] + 1 << ' ' << t[2] + 1 << '\n';
}

}  // namespace rodfab::testing
