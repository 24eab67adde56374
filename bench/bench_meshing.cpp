// meshing/: the simplifiers compared on one input (CGAL edge collapse with Garland-Heckbert plane
// quadrics, as rods-from-mesh uses it, and with Lindstrom-Turk; OpenMesh's quadric decimater), and
// the whole rods-from-mesh on a 350,000-triangle mesh. Input: a bumpy sphere (radius 40 mm,
// tests/meshing/mesh_fixtures.hpp), frequency 132: 348,480 triangles.
// Counters: the simplified mesh's faces; its distance from the original (largest and RMS over the
// original's vertices, mm); its smallest triangle angle and the share of triangles with an angle
// below 20 degrees (slivers make crooked rods).
#include "geometry/design_file.hpp"
#include "meshing/mesh.hpp"
#include "meshing/meshing.hpp"
#include "tests/meshing/mesh_fixtures.hpp"
#include "tests/meshing/step_text.hpp"

#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Bounded_normal_change_placement.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Count_stop_predicate.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/LindstromTurk.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>
#include <benchmark/benchmark.h>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace {

using namespace rodfab;
using meshing::TriangleMesh;
using meshing::Vec3;
constexpr int kFrequency = 132;
constexpr std::size_t kTargetFaces = 267;  // about 400 rods

const TriangleMesh& input() {
  static const TriangleMesh mesh = [] {
    const testing::SimpleMesh m = testing::bumpySphere(kFrequency, 40);
    TriangleMesh out{m.points, {}};
    for (const auto& t : m.triangles) out.triangles.push_back({t[0], t[1], t[2]});
    return out;
  }();
  return mesh;
}

TriangleMesh cgalLindstromTurk(const TriangleMesh& in, std::size_t faces) {
  using Kernel = CGAL::Simple_cartesian<double>;
  using Mesh = CGAL::Surface_mesh<Kernel::Point_3>;
  namespace SMS = CGAL::Surface_mesh_simplification;
  Mesh mesh;
  for (const Vec3& p : in.points) mesh.add_vertex(Kernel::Point_3(p.x(), p.y(), p.z()));
  for (const auto& t : in.triangles) mesh.add_face(Mesh::Vertex_index(t[0]), Mesh::Vertex_index(t[1]), Mesh::Vertex_index(t[2]));
  SMS::Count_stop_predicate<Mesh> stop(faces * 3 / 2);
  SMS::edge_collapse(mesh, stop, CGAL::parameters::get_cost(SMS::LindstromTurk_cost<Mesh>())
                                     .get_placement(SMS::Bounded_normal_change_placement<SMS::LindstromTurk_placement<Mesh>>()));
  mesh.collect_garbage();
  TriangleMesh out;
  for (auto v : mesh.vertices()) out.points.emplace_back(mesh.point(v).x(), mesh.point(v).y(), mesh.point(v).z());
  for (auto f : mesh.faces()) {
    meshing::Triangle t{};
    int k = 0;
    for (auto v : CGAL::vertices_around_face(mesh.halfedge(f), mesh)) t[k++] = static_cast<std::uint32_t>(v.idx());
    out.triangles.push_back(t);
  }
  return out;
}

TriangleMesh openMeshQuadric(const TriangleMesh& in, std::size_t faces) {
  using Mesh = OpenMesh::TriMesh_ArrayKernelT<>;
  Mesh mesh;
  std::vector<Mesh::VertexHandle> v;
  for (const Vec3& p : in.points) v.push_back(mesh.add_vertex(Mesh::Point(p.x(), p.y(), p.z())));
  for (const auto& t : in.triangles) mesh.add_face(v[t[0]], v[t[1]], v[t[2]]);
  OpenMesh::Decimater::DecimaterT<Mesh> decimater(mesh);
  OpenMesh::Decimater::ModQuadricT<Mesh>::Handle quadric;
  OpenMesh::Decimater::ModNormalFlippingT<Mesh>::Handle flipping;
  decimater.add(quadric);
  decimater.add(flipping);
  decimater.initialize();
  decimater.decimate_to_faces(0, faces);
  mesh.garbage_collection();
  TriangleMesh out;
  for (auto vh : mesh.vertices()) out.points.emplace_back(mesh.point(vh)[0], mesh.point(vh)[1], mesh.point(vh)[2]);
  for (auto fh : mesh.faces()) {
    meshing::Triangle t{};
    int k = 0;
    for (auto vh : mesh.fv_range(fh)) t[k++] = static_cast<std::uint32_t>(vh.idx());
    out.triangles.push_back(t);
  }
  return out;
}

void report(benchmark::State& state, const TriangleMesh& simplified) {
  const meshing::SurfaceProjector surface(simplified);
  double largest = 0, squares = 0;
  for (const Vec3& p : input().points) {
    const double d = surface.distance(p);
    largest = std::max(largest, d), squares += d * d;
  }
  double smallestAngle = 180;
  std::size_t slivers = 0;
  for (const auto& t : simplified.triangles) {
    double worst = 180;
    for (int k = 0; k < 3; ++k) {
      const Vec3 a = simplified.points[t[(k + 1) % 3]] - simplified.points[t[k]], b = simplified.points[t[(k + 2) % 3]] - simplified.points[t[k]];
      worst = std::min(worst, std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180 / M_PI);
    }
    smallestAngle = std::min(smallestAngle, worst);
    slivers += worst < 20;
  }
  state.counters["faces"] = static_cast<double>(simplified.triangles.size());
  state.counters["dist_max_mm"] = largest;
  state.counters["dist_rms_mm"] = std::sqrt(squares / input().points.size());
  state.counters["min_angle_deg"] = smallestAngle;
  state.counters["below_20deg_pct"] = 100.0 * slivers / simplified.triangles.size();
}

template <typename Simplify>
void simplifyBench(benchmark::State& state, Simplify simplify) {
  const TriangleMesh& mesh = input();
  TriangleMesh out;
  for (auto _ : state) out = simplify(mesh, kTargetFaces);
  report(state, out);
}

void BM_cgal_garland_heckbert(benchmark::State& s) { simplifyBench(s, meshing::simplifyMesh); }
void BM_cgal_lindstrom_turk(benchmark::State& s) { simplifyBench(s, cgalLindstromTurk); }
void BM_openmesh_quadric(benchmark::State& s) { simplifyBench(s, openMeshQuadric); }
BENCHMARK(BM_cgal_garland_heckbert)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_cgal_lindstrom_turk)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(BM_openmesh_quadric)->Unit(benchmark::kMillisecond)->Iterations(1);

// The command's work from a binary STL file: read, weld, check, simplify, project, interpolate.
void BM_rods_from_mesh_350k(benchmark::State& state) {
  const std::filesystem::path file = std::filesystem::temp_directory_path() / "rodfab-bench-bumpy-350k.stl";
  testing::writeBinaryStl(testing::bumpySphere(kFrequency, 40), file.string());
  meshing::MeshRodOptions options;
  options.faces = static_cast<int>(kTargetFaces);
  meshing::MeshRods result;
  for (auto _ : state) result = meshing::rodsFromMesh(file, options);
  std::filesystem::remove(file);
  state.counters["rods"] = static_cast<double>(result.report.rods);
  state.counters["read_s"] = result.report.readSeconds;
  state.counters["simplify_s"] = result.report.simplifySeconds;
  state.counters["rods_s"] = result.report.rodSeconds;
  state.counters["surface_dist_mm"] = result.report.largestSurfaceDistance;
}
BENCHMARK(BM_rods_from_mesh_350k)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

// A STEP curve set of `count` cubic B-splines of 40 control points winding 0.3 mm to and fro every
// 0.05 mm along x while they rise (3 mm apart on a grid): ~0.7 MB of rod samples each at a 0.4 mm
// diameter, the costliest kind of rod to build measured (meshing/README.md).
std::string windingSplinesStep(int count) {
  std::string data, set;
  int id = 100;
  char line[160];
  for (int i = 0; i < count; ++i) {
    std::string poles, multiplicities = "4", parameters = "0.";
    for (int k = 0; k < 40; ++k, ++id) {
      std::snprintf(line, sizeof line, "#%d=CARTESIAN_POINT('',(%.4f,%.4f,%.4f));\n", id, (i % 200) * 3 + k * 0.05,
                    (i / 200) * 3 + 0.3 * ((k * 7) % 5), k * 0.1);
      data += line;
      std::snprintf(line, sizeof line, "%s#%d", k ? "," : "", id);
      poles += line;
    }
    for (int p = 1; p < 38; ++p) {
      std::snprintf(line, sizeof line, ",%d.", p);
      parameters += line;
      multiplicities += p < 37 ? ",1" : ",4";
    }
    std::snprintf(line, sizeof line, "#%d=B_SPLINE_CURVE_WITH_KNOTS('',3,(", id);
    data += line + poles + "),.UNSPECIFIED.,.F.,.F.,(" + multiplicities + "),(" + parameters + "),.UNSPECIFIED.);\n";
    std::snprintf(line, sizeof line, "%s#%d", i ? "," : "", id++);
    set += line;
  }
  return cad_test::stepModel("#15=GEOMETRIC_CURVE_SET('',(" + set + "));\n" + data);
}

// rods-from-cad's work on 200 winding splines: the reader process (OpenCASCADE, each rod built once to
// check it, on both cores) and rodfab's parse of its design (every rod built again, on both cores).
void BM_rods_from_cad_winding_200(benchmark::State& state) {
  const std::filesystem::path file = std::filesystem::temp_directory_path() / "rodfab-bench-winding-200.step";
  std::ofstream(file) << windingSplinesStep(200);
  meshing::CadRodOptions options;
  options.section = geometry::Section::circle(0.4);
  meshing::CadRods result;
  for (auto _ : state) result = meshing::rodsFromCad(file, options);
  state.counters["rods"] = static_cast<double>(result.report.rods);
  state.counters["file_MB"] = static_cast<double>(std::filesystem::file_size(file)) / 1e6;
  std::filesystem::remove(file);
}
BENCHMARK(BM_rods_from_cad_winding_200)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

// Reading the design rods-from-cad wrote of them (geometry::parseDesign: the rods checked in order,
// then built on `threads` threads).
void BM_parse_design_winding_200(benchmark::State& state) {
  static const std::string text = [] {
    const std::filesystem::path file = std::filesystem::temp_directory_path() / "rodfab-bench-winding-200-parse.step";
    std::ofstream(file) << windingSplinesStep(200);
    meshing::CadRodOptions options;
    options.section = geometry::Section::circle(0.4);
    const meshing::CadRods cad = meshing::rodsFromCad(file, options);
    std::filesystem::remove(file);
    return geometry::designToJson(cad.structure).dump();
  }();
  const tbb::global_control threads(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(state.range(0)));
  std::size_t rods = 0;
  for (auto _ : state) rods = geometry::parseDesign(text, "winding.json").rods.size();
  state.counters["rods"] = static_cast<double>(rods);
  state.counters["design_MB"] = static_cast<double>(text.size()) / 1e6;
}
BENCHMARK(BM_parse_design_winding_200)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
