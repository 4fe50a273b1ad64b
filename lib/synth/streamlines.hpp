#pragma once
// Streamline integration in a FlowField and the flow measures the synthetic data sets map to
// transparency.

#include <glm/mat3x3.hpp>
#include <vector>

#include "synth/flow_fields.hpp"

namespace linebake::synth {

struct IntegrationOptions {
  double step = 0.05;       // arc-length step (fixed), or initial step (adaptive)
  bool adaptive = false;    // RK4 with step doubling and error control
  double tolerance = 1e-5;  // adaptive: max position error per step
  double min_step = 1e-4;   // adaptive bounds
  double max_step = 0.5;
  uint32_t max_points = 256;    // stop at this many points (max length)
  double min_speed = 1e-6;      // stop at stagnation: |v| below this
  bool both_directions = true;  // integrate backward and forward from the seed
};

// Integrates dx/ds = v/|v| (arc length) with RK4 from `seed`. Stops at domain exit (the last
// point is inside the domain), stagnation, or max_points.
std::vector<dvec3> integrate_streamline(const FlowField& field, const dvec3& seed,
                                        const IntegrationOptions& options);

// Velocity gradient J[i][j] = d v_j / d x_i... stored as glm column-major: J[col][row] =
// d v_row / d x_col, by central differences with step h.
glm::dmat3 velocity_gradient(const FlowField& field, const dvec3& p, double h);
double vorticity_magnitude(const glm::dmat3& gradient);
// lambda2 (Jeong & Hussain): the middle eigenvalue of S^2 + Omega^2; negative inside vortices.
double lambda2(const glm::dmat3& gradient);
// Eigenvalues of a symmetric 3x3 matrix, ascending (closed form).
glm::dvec3 symmetric_eigenvalues(const glm::dmat3& m);

}  // namespace linebake::synth
