#pragma once
// Analytic flow fields standing in for the paper's four data sets (which cannot be downloaded
// here). Each has the character of its original: a vessel with a swirling saccular bulge,
// Rayleigh-Benard rolls in a flat box, multi-scale turbulence, and a convective boundary layer.

#include <cstdint>
#include <glm/vec3.hpp>
#include <memory>
#include <string>
#include <vector>

namespace linebake::synth {

using glm::dvec3;

// Deterministic, platform-independent random numbers (splitmix64).
class Rng {
 public:
  explicit Rng(uint64_t seed) : state_(seed) {}
  uint64_t next();
  double uniform();  // [0, 1)
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }

 private:
  uint64_t state_;
};

class FlowField {
 public:
  virtual ~FlowField() = default;
  virtual dvec3 velocity(const dvec3& p) const = 0;
  virtual bool inside(const dvec3& p) const = 0;
  virtual dvec3 domain_min() const = 0;
  virtual dvec3 domain_max() const = 0;
  // A seed point inside the domain (uniform by rejection in the bounding box by default).
  virtual dvec3 seed(Rng& rng) const;
};

std::unique_ptr<FlowField> make_aneurysm_field(uint64_t seed);
std::unique_ptr<FlowField> make_convection_field(uint64_t seed);
std::unique_ptr<FlowField> make_turbulence_field(uint64_t seed);
std::unique_ptr<FlowField> make_clouds_field(uint64_t seed);

}  // namespace linebake::synth
