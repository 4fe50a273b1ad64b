#include "synth/flow_fields.hpp"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <numbers>

namespace linebake::synth {

using std::numbers::pi;

uint64_t Rng::next() {
  uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

double Rng::uniform() {
  return static_cast<double>(next() >> 11) * 0x1.0p-53;
}

dvec3 FlowField::seed(Rng& rng) const {
  const dvec3 lo = domain_min(), hi = domain_max();
  for (;;) {
    const dvec3 p{rng.uniform(lo.x, hi.x), rng.uniform(lo.y, hi.y), rng.uniform(lo.z, hi.z)};
    if (inside(p)) return p;
  }
}

namespace {

double smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

// A straight vessel along x (radius 1) with a saccular aneurysm on its side: Poiseuille flow in
// the vessel, a swirling vortex inside the bulge driven by the shear at its neck.
class Aneurysm final : public FlowField {
 public:
  explicit Aneurysm(uint64_t seed) {
    Rng rng(seed);
    bulge_center_ = {rng.uniform(-0.3, 0.3), 1.45, rng.uniform(-0.2, 0.2)};
    swirl_tilt_ = rng.uniform(0.15, 0.3);
  }
  dvec3 velocity(const dvec3& p) const override {
    const double r2 = p.y * p.y + p.z * p.z;
    const dvec3 parent{std::max(0.0, 1.0 - r2), 0, 0};
    const dvec3 d = p - bulge_center_;
    const double falloff = std::max(0.0, 1.0 - glm::dot(d, d) / (kBulgeRadius * kBulgeRadius));
    // Rotation about a slightly tilted z axis plus a secondary flow that makes helices.
    const dvec3 axis = glm::normalize(dvec3{swirl_tilt_, 0, 1});
    dvec3 swirl = 1.6 * falloff * glm::cross(axis, d);
    swirl += 0.35 * falloff * dvec3{0, 0, std::sin(pi * d.y / kBulgeRadius)};
    const double w = smoothstep(0.65, 1.1, p.y);
    return (1 - w) * parent + w * swirl;
  }
  bool inside(const dvec3& p) const override {
    const bool in_vessel = std::fabs(p.x) < kHalfLength && p.y * p.y + p.z * p.z < 1.0;
    const dvec3 d = p - bulge_center_;
    return in_vessel || glm::dot(d, d) < kBulgeRadius * kBulgeRadius;
  }
  dvec3 domain_min() const override { return {-kHalfLength, -1, -1.2}; }
  dvec3 domain_max() const override { return {kHalfLength, 2.6, 1.2}; }

 private:
  static constexpr double kHalfLength = 6.0;
  static constexpr double kBulgeRadius = 1.1;
  dvec3 bulge_center_;
  double swirl_tilt_;
};

// Rayleigh-Benard-like convection rolls between a hot floor (y = 0) and a cold lid (y = 1) in a
// flat 16 x 1 x 16 box. Roll axes wander along z; a weak axial flow turns loops into helices.
class Convection final : public FlowField {
 public:
  explicit Convection(uint64_t seed) {
    Rng rng(seed);
    wave_phase_ = rng.uniform(0, 2 * pi);
    axial_ = rng.uniform(0.15, 0.3);
  }
  dvec3 velocity(const dvec3& p) const override {
    // Stream function psi = sin(pi * xi) sin(pi * y) with xi = x + 0.3 sin(2 pi z / 8 + phase);
    // u = d psi / dy, v = -d psi / dx keeps the (u, v) part divergence-free, and w depends on
    // x and y only.
    const double xi = p.x + 0.3 * std::sin(2 * pi * p.z / 8 + wave_phase_);
    const double u = pi * std::sin(pi * xi) * std::cos(pi * p.y);
    const double v = -pi * std::cos(pi * xi) * std::sin(pi * p.y);
    const double w = axial_ * pi * std::sin(pi * p.y) * std::cos(0.5 * pi * p.x);
    return {u, v, w};
  }
  bool inside(const dvec3& p) const override {
    return p.x > 0 && p.x < 16 && p.y > 0 && p.y < 1 && p.z > 0 && p.z < 16;
  }
  dvec3 domain_min() const override { return {0, 0, 0}; }
  dvec3 domain_max() const override { return {16, 1, 16}; }

 private:
  double wave_phase_;
  double axial_;
};

// Forced-turbulence stand-in in a 2 pi box: an ABC flow plus random divergence-free Fourier
// modes a cos(k.x + phi) with a perpendicular to k and |a| ~ |k|^(-5/6) (a -5/3 spectrum).
class Turbulence final : public FlowField {
 public:
  explicit Turbulence(uint64_t seed) {
    Rng rng(seed);
    for (int i = 0; i < 48; ++i) {
      const double kmag = 1.0 + 7.0 * rng.uniform();
      const double cz = rng.uniform(-1, 1), phi = rng.uniform(0, 2 * pi);
      const double sz = std::sqrt(1 - cz * cz);
      const dvec3 k = kmag * dvec3{sz * std::cos(phi), sz * std::sin(phi), cz};
      dvec3 a = glm::cross(k, dvec3{rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)});
      if (glm::length(a) < 1e-9) a = glm::cross(k, dvec3{0, 0, 1});
      a = glm::normalize(a) * 0.9 * std::pow(kmag, -5.0 / 6.0);
      modes_.push_back({k, a, rng.uniform(0, 2 * pi)});
    }
  }
  dvec3 velocity(const dvec3& p) const override {
    dvec3 v{0.5 * std::sin(p.z) + 0.35 * std::cos(p.y), 0.35 * std::sin(p.x) + 0.2 * std::cos(p.z),
            0.2 * std::sin(p.y) + 0.5 * std::cos(p.x)};
    for (const Mode& m : modes_) v += m.a * std::cos(glm::dot(m.k, p) + m.phase);
    return v;
  }
  bool inside(const dvec3& p) const override {
    return p.x > 0 && p.y > 0 && p.z > 0 && p.x < 2 * pi && p.y < 2 * pi && p.z < 2 * pi;
  }
  dvec3 domain_min() const override { return {0, 0, 0}; }
  dvec3 domain_max() const override { return dvec3{2 * pi}; }

 private:
  struct Mode {
    dvec3 k, a;
    double phase;
  };
  std::vector<Mode> modes_;
};

// A convective boundary layer (38.4 x 38.4 x 13, like the 384 x 384 x 130 LES grid): a sheared
// logarithmic wind plus thermals on a jittered lattice. Each thermal is an axisymmetric
// divergence-free cell with Stokes stream function W s^2/2 (1 - exp(-r^2/s^2)) sin(pi z / H),
// tapered to zero at one lattice spacing so only the 3 x 3 neighbouring cells are evaluated.
class Clouds final : public FlowField {
 public:
  explicit Clouds(uint64_t seed) {
    Rng rng(seed);
    for (int j = 0; j < kCells; ++j)
      for (int i = 0; i < kCells; ++i) {
        const double cx = (i + 0.5 + rng.uniform(-0.25, 0.25)) * kSpacing;
        const double cy = (j + 0.5 + rng.uniform(-0.25, 0.25)) * kSpacing;
        plumes_.push_back({cx, cy, rng.uniform(0.7, 1.5), rng.uniform(0.8, 2.5)});
      }
  }
  dvec3 velocity(const dvec3& p) const override {
    const double zn = std::clamp(p.z / kHeight, 0.0, 1.0);
    const double wind = 1.2 * std::log1p(p.z / 0.1) / std::log1p(kHeight / 0.1);
    dvec3 v{wind * std::cos(0.6 * zn), wind * std::sin(0.6 * zn), 0};
    const int ci = static_cast<int>(std::floor(p.x / kSpacing));
    const int cj = static_cast<int>(std::floor(p.y / kSpacing));
    for (int j = std::max(cj - 1, 0); j <= std::min(cj + 1, kCells - 1); ++j)
      for (int i = std::max(ci - 1, 0); i <= std::min(ci + 1, kCells - 1); ++i) {
        const Plume& pl = plumes_[j * kCells + i];
        const double dx = p.x - pl.x, dy = p.y - pl.y;
        const double r2 = dx * dx + dy * dy;
        if (r2 >= kSpacing * kSpacing) continue;
        const double r = std::sqrt(r2);
        const double taper = 1 - smoothstep(0.5 * kSpacing, kSpacing, r);
        const double s2 = pl.sigma * pl.sigma;
        const double e = std::exp(-r2 / s2);
        v.z += taper * pl.strength * e * std::sin(pi * zn);
        if (r > 1e-9) {
          const double ur =
              -taper * pl.strength * 0.5 * s2 * (1 - e) / r * (pi / kHeight) * std::cos(pi * zn);
          v.x += ur * dx / r;
          v.y += ur * dy / r;
        }
      }
    return v;
  }
  bool inside(const dvec3& p) const override {
    return p.x > 0 && p.y > 0 && p.z > 0 && p.x < kSize && p.y < kSize && p.z < kHeight;
  }
  dvec3 domain_min() const override { return {0, 0, 0}; }
  dvec3 domain_max() const override { return {kSize, kSize, kHeight}; }

 private:
  static constexpr int kCells = 8;
  static constexpr double kSpacing = 4.8;
  static constexpr double kSize = kCells * kSpacing;
  static constexpr double kHeight = 13.0;
  struct Plume {
    double x, y, sigma, strength;
  };
  std::vector<Plume> plumes_;
};

}  // namespace

std::unique_ptr<FlowField> make_aneurysm_field(uint64_t seed) {
  return std::make_unique<Aneurysm>(seed);
}
std::unique_ptr<FlowField> make_convection_field(uint64_t seed) {
  return std::make_unique<Convection>(seed);
}
std::unique_ptr<FlowField> make_turbulence_field(uint64_t seed) {
  return std::make_unique<Turbulence>(seed);
}
std::unique_ptr<FlowField> make_clouds_field(uint64_t seed) {
  return std::make_unique<Clouds>(seed);
}

}  // namespace linebake::synth
