// The benchmark designs (issue 17's classes): spring, lattices of straight and curved rods, dense block.
#include "examples/example_designs.hpp"
#include "examples/example_curves.hpp"

#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace rodfab::examples {

using namespace detail;

namespace {

// The lattice with node (i, j, k) at origin + spacing * (i, j, k) (componentwise): every centerline is
// the same affine image of the lattice in node units, so its extent scales per axis with `spacing`.
RodStructure cubicLattice(const LatticeParameters& p, const Vec3& origin, const Vec3& spacing, double envelopeHeight) {
  RodStructure s;
  s.source = p.bow > 0.0 ? "curved-lattice" : "lattice";
  auto place = [&](const Vec3& unit) { return Vec3(origin + spacing.cwiseProduct(unit)); };
  auto modulusAt = [&](double z) {
    const double t = std::abs(z / envelopeHeight - 0.5) * 2.0;
    return 8.0 + 112.0 * t * t;
  };
  const char* axisName[3] = {"x-", "y-", "z-"};
  for (int axis = 0; axis < 3; ++axis) {
    const Eigen::Vector3i step = Eigen::Vector3i::Unit(axis);
    const Vec3 side = Vec3::Unit((axis + 1) % 3);
    std::size_t n = 0;
    for (int k = 0; k + step.z() < p.nodes.z(); ++k)
      for (int j = 0; j + step.y() < p.nodes.y(); ++j)
        for (int i = 0; i + step.x() < p.nodes.x(); ++i) {
          const Vec3 a(i, j, k), b = a + step.cast<double>();
          const double sign = (i + j + k) % 2 == 0 ? 1.0 : -1.0;
          const auto path = [&](double t) { return place(a + t * (b - a) + sign * p.bow * std::sin(kPi * t) * side); };
          NurbsCurve curve = p.bow > 0.0 ? cubicThrough(path) : straight(place(a), place(b));
          const BSplineField modulus = threePointModulus(modulusAt(path(0.0).z()), modulusAt(path(0.5).z()), modulusAt(path(1.0).z()));
          s.rods.push_back(circleRod(numbered(axisName[axis], n++), std::move(curve), p.rodDiameter, modulus));
        }
  }
  return s;
}

}  // namespace

RodStructure cubicLatticeScaledTo(const Vec3& envelope, const LatticeParameters& p) {
  if ((p.nodes.array() < 2).any() || !(p.rodDiameter > 0.0) || !(p.bow >= 0.0) || !((envelope.array() > p.rodDiameter).all()))
    throw std::invalid_argument("cubic lattice: need at least 2 nodes per axis, a positive diameter below the envelope, bow >= 0");
  // The solid reaches one radius beyond its centerlines on every side (caps, and the sections where a
  // bow peaks). Measure the centerlines' extent once in node units (a trial spacing), then solve for
  // the spacing and origin that put the solid at [0, envelope].
  const Vec3 trial = (envelope.array() / (p.nodes.cast<double>().array() - 1.0)).matrix();
  const geometry::Box3 b = cubicLattice(p, Vec3::Zero(), trial, envelope.z()).bounds();
  const double r = 0.5 * p.rodDiameter;
  const Vec3 unitMin = ((b.min().array() + r) / trial.array()).matrix();
  const Vec3 unitExtent = ((b.sizes().array() - p.rodDiameter) / trial.array()).matrix();
  const Vec3 spacing = ((envelope.array() - p.rodDiameter) / unitExtent.array()).matrix();
  return cubicLattice(p, (r - spacing.array() * unitMin.array()).matrix(), spacing, envelope.z());
}

RodStructure denseBlock(const Vec3& size) {
  RodStructure s;
  s.source = "dense-block";
  const NurbsCurve axis = straight(Vec3(0, 0.5 * size.y(), 0.5 * size.z()), Vec3(size.x(), 0.5 * size.y(), 0.5 * size.z()));
  s.rods.emplace_back("block", axis, Section::rectangle(size.y(), size.z()), Vec3(0, 1, 0), std::nullopt, CapStyle::Flat,
                      BSplineField(1, {0, 0, 1, 1}, {8.0, 190.0}));
  return s;
}

std::vector<std::string> benchmarkClasses() { return {"spring", "lattice", "curved-lattice", "dense"}; }

RodStructure benchmarkDesign(const std::string& name) {
  const Vec3 envelope(84.6, 84.6, 90.0);  // 2000 x 1000 x 3000 Connex3 voxels
  if (name == "spring") return bucklingSpringScaledTo(envelope);
  if (name == "lattice") return cubicLatticeScaledTo(envelope);
  if (name == "curved-lattice") {
    LatticeParameters p;
    p.bow = 0.15;
    return cubicLatticeScaledTo(envelope, p);
  }
  if (name == "dense") return denseBlock();
  throw std::invalid_argument("unknown benchmark design '" + name + "' (expected spring, lattice, curved-lattice or dense)");
}

}  // namespace rodfab::examples
