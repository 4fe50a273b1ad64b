#include "synth/streamlines.hpp"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <numbers>

namespace linebake::synth {

namespace {

// Unit direction of the flow, or nothing at stagnation.
bool direction(const FlowField& field, const dvec3& p, double sign, double min_speed, dvec3& out) {
  const dvec3 v = field.velocity(p);
  const double speed = glm::length(v);
  if (!(speed > min_speed)) return false;
  out = sign * v / speed;
  return true;
}

bool rk4_step(const FlowField& field, const dvec3& p, double h, double sign, double min_speed,
              dvec3& out) {
  dvec3 k1, k2, k3, k4;
  if (!direction(field, p, sign, min_speed, k1)) return false;
  if (!direction(field, p + 0.5 * h * k1, sign, min_speed, k2)) return false;
  if (!direction(field, p + 0.5 * h * k2, sign, min_speed, k3)) return false;
  if (!direction(field, p + h * k3, sign, min_speed, k4)) return false;
  out = p + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
  return true;
}

// Points after the seed in one direction.
std::vector<dvec3> trace(const FlowField& field, const dvec3& seed, const IntegrationOptions& o,
                         double sign, uint32_t max_points) {
  std::vector<dvec3> points;
  dvec3 p = seed;
  double h = o.step;
  while (points.size() < max_points) {
    dvec3 next;
    if (!o.adaptive) {
      if (!rk4_step(field, p, h, sign, o.min_speed, next)) break;
    } else {
      // Step doubling: one step of h against two of h/2; the difference estimates the error.
      dvec3 full, half, two_halves;
      if (!rk4_step(field, p, h, sign, o.min_speed, full) ||
          !rk4_step(field, p, 0.5 * h, sign, o.min_speed, half) ||
          !rk4_step(field, half, 0.5 * h, sign, o.min_speed, two_halves))
        break;
      const double error = glm::length(full - two_halves);
      if (error > o.tolerance && h > o.min_step) {
        h = std::max(0.5 * h, o.min_step);
        continue;
      }
      next = two_halves;
      if (error < o.tolerance / 32) h = std::min(2 * h, o.max_step);
    }
    if (!field.inside(next)) break;
    points.push_back(next);
    p = next;
  }
  return points;
}

}  // namespace

std::vector<dvec3> integrate_streamline(const FlowField& field, const dvec3& seed,
                                        const IntegrationOptions& o) {
  if (o.max_points == 0 || !field.inside(seed)) return {};
  std::vector<dvec3> line;
  const uint32_t remaining = o.max_points - 1;
  if (o.both_directions) {
    std::vector<dvec3> back = trace(field, seed, o, -1.0, remaining / 2);
    line.assign(back.rbegin(), back.rend());
  }
  line.push_back(seed);
  const auto forward_budget = static_cast<uint32_t>(o.max_points - line.size());
  std::vector<dvec3> forward = trace(field, seed, o, 1.0, forward_budget);
  line.insert(line.end(), forward.begin(), forward.end());
  return line;
}

glm::dmat3 velocity_gradient(const FlowField& field, const dvec3& p, double h) {
  glm::dmat3 g;
  for (int axis = 0; axis < 3; ++axis) {
    dvec3 d{0};
    d[axis] = h;
    g[axis] = (field.velocity(p + d) - field.velocity(p - d)) / (2 * h);
  }
  return g;
}

double vorticity_magnitude(const glm::dmat3& g) {
  // g[col][row] = d v_row / d x_col
  const double wx = g[1][2] - g[2][1];  // dvz/dy - dvy/dz
  const double wy = g[2][0] - g[0][2];  // dvx/dz - dvz/dx
  const double wz = g[0][1] - g[1][0];  // dvy/dx - dvx/dy
  return std::sqrt(wx * wx + wy * wy + wz * wz);
}

glm::dvec3 symmetric_eigenvalues(const glm::dmat3& m) {
  // Smith's trigonometric method.
  const double p1 = m[0][1] * m[0][1] + m[0][2] * m[0][2] + m[1][2] * m[1][2];
  const double q = (m[0][0] + m[1][1] + m[2][2]) / 3;
  if (p1 == 0) {
    glm::dvec3 e{m[0][0], m[1][1], m[2][2]};
    std::sort(&e[0], &e[0] + 3);
    return e;
  }
  const double p2 = (m[0][0] - q) * (m[0][0] - q) + (m[1][1] - q) * (m[1][1] - q) +
                    (m[2][2] - q) * (m[2][2] - q) + 2 * p1;
  const double p = std::sqrt(p2 / 6);
  const glm::dmat3 b = (1 / p) * (m - q * glm::dmat3(1.0));
  const double r = std::clamp(glm::determinant(b) / 2, -1.0, 1.0);
  const double phi = std::acos(r) / 3;
  const double e1 = q + 2 * p * std::cos(phi);
  const double e3 = q + 2 * p * std::cos(phi + 2 * std::numbers::pi / 3);
  const double e2 = 3 * q - e1 - e3;
  return {e3, e2, e1};
}

double lambda2(const glm::dmat3& g) {
  const glm::dmat3 s = 0.5 * (g + glm::transpose(g));
  const glm::dmat3 w = 0.5 * (g - glm::transpose(g));
  return symmetric_eigenvalues(s * s + w * w)[1];
}

}  // namespace linebake::synth
