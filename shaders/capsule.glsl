// Capsule-chain crossings in float32: the port of intersect_capsule() in
// lib/accel/capsule_chain.cpp (the union surface of a line's capsules; a joint sphere belongs to
// the segment it ends). Shared by rtx_capsules.rint and the lavapipe test shader capsule_test.comp,
// which checks it against the CPU code.

#ifndef CAPSULE_COORDINATE_ERROR
#define CAPSULE_COORDINATE_ERROR 0.0
#endif

struct CapsuleSegment {
  vec3 before;  // the previous segment's first point (flags & 1)
  vec3 p0, p1;
  vec3 after;   // the next segment's last point (flags & 2)
  float radius;
  uint flags;
};

float capsule_distance_to_segment(vec3 x, vec3 a, vec3 b) {
  const vec3 axis = b - a;
  const float length2 = dot(axis, axis);
  const float h = length2 > 0.0 ? clamp(dot(x - a, axis) / length2, 0.0, 1.0) : 0.0;
  return length(x - (a + h * axis));
}

// Real roots of a t^2 + b t + c, ascending (the cancellation-free form); returns the count.
int capsule_solve_quadratic(float a, float b, float c, out float r0, out float r1) {
  r0 = 0.0;
  r1 = 0.0;
  const float discriminant = b * b - 4.0 * a * c;
  if (a == 0.0 || discriminant < 0.0) return 0;
  const float q = -0.5 * (b + (b >= 0.0 ? sqrt(discriminant) : -sqrt(discriminant)));
  r0 = q / a;
  r1 = q != 0.0 ? c / q : r0;
  if (r0 > r1) {
    const float s = r0;
    r0 = r1;
    r1 = s;
  }
  return 2;
}

// The ray's roots against the infinite cylinder of radius s.radius about the segment's unit
// `axis`, ascending (the count, as capsule_solve_quadratic); the outward normal at root t is
// w_perp + t d_perp, the parts of origin - s.p0 and of direction across the axis.
int capsule_cylinder_roots(CapsuleSegment s, vec3 origin, vec3 direction, vec3 axis,
                           out float r0, out float r1, out vec3 w_perp, out vec3 d_perp) {
  const vec3 w = origin - s.p0;
  d_perp = direction - dot(direction, axis) * axis;
  w_perp = w - dot(w, axis) * axis;
  return capsule_solve_quadratic(dot(d_perp, d_perp), 2.0 * dot(w_perp, d_perp),
                                 dot(w_perp, w_perp) - s.radius * s.radius, r0, r1);
}

// The ray's roots against the sphere of radius r about `centre`, ascending (the count).
int capsule_sphere_roots(vec3 centre, float r, vec3 origin, vec3 direction, out float r0,
                         out float r1) {
  const vec3 w = origin - centre;
  return capsule_solve_quadratic(dot(direction, direction), 2.0 * dot(w, direction),
                                 dot(w, w) - r * r, r0, r1);
}

// Whether crossing x, at t along a ray from `origin` (extent: its distance from s.p0), lies
// inside a neighbouring segment's capsule, where the joint hands the surface over to that
// segment: inside by more than the float error of the hit point (relative error about 2^-23 of
// the ray's extent); the CPU code, in double, uses r (1 - 1e-6). The points' own coordinates
// carry float error too (about 2^-23 of their magnitude): with CAPSULE_COORDINATE_ERROR 1 a
// crossing that close to a neighbour is kept, and the caller removes the double it may make
// (tiles does; a chain of short, slightly bent segments otherwise loses crossings that both
// sides of a joint reject).
bool capsule_in_neighbour(CapsuleSegment s, vec3 x, float t, float extent) {
  const vec3 magnitude = abs(x);
  const float inside =
      s.radius * (1.0 - 1e-6) -
      8.0 * 1.1920929e-7 *
          (extent + abs(t) +
           CAPSULE_COORDINATE_ERROR * max(magnitude.x, max(magnitude.y, magnitude.z)));
  return ((s.flags & 1u) != 0u && capsule_distance_to_segment(x, s.before, s.p0) < inside) ||
         ((s.flags & 2u) != 0u && capsule_distance_to_segment(x, s.p1, s.after) < inside);
}

// Crossings of origin + t direction (unit direction) with the surface `s` owns, nearest first:
// t, the unit outward normal, and the position along the segment u in [0, 1]. The arrays are
// indexed by constants only (loops of fixed trips, unrolled): a variable index into a private
// array costs about the whole array on lavapipe (tiles_composite.glsl).
int capsule_crossings(CapsuleSegment s, vec3 origin, vec3 direction, out float t[4],
                      out vec3 normal[4], out float u[4]) {
  int count = 0;
  for (int k = 0; k < 4; ++k) {
    t[k] = 0.0;
    normal[k] = vec3(0.0);
    u[k] = 0.0;
  }
  const float r = s.radius;
  const float extent = length(origin - s.p0);
  const vec3 axis_vector = s.p1 - s.p0;
  const float len = length(axis_vector);
  const vec3 axis = len > 0.0 ? axis_vector / len : vec3(0.0);
  float candidate_t[4];
  vec3 candidate_n[4];
  int candidates = 0;
  float r0, r1;
  // The cylinder between the end planes.
  if (len > 0.0) {
    vec3 w_perp, d_perp;
    const int n = capsule_cylinder_roots(s, origin, direction, axis, r0, r1, w_perp, d_perp);
    for (int k = 0; k < 2; ++k) {
      if (k >= n) continue;
      const float root = k == 0 ? r0 : r1;
      const float h = dot(origin - s.p0 + root * direction, axis);
      if (h >= 0.0 && h <= len && candidates < 4) {
        for (int j = 0; j < 4; ++j)
          if (j == candidates) {
            candidate_t[j] = root;
            candidate_n[j] = w_perp + root * d_perp;
          }
        ++candidates;
      }
    }
  }
  // The end sphere beyond p1; the start sphere only on a line's first segment.
  for (int end = 0; end < 2; ++end) {
    if (end == 1 && (s.flags & 1u) != 0u) break;
    const vec3 centre = end == 0 ? s.p1 : s.p0;
    const int n = capsule_sphere_roots(centre, r, origin, direction, r0, r1);
    for (int k = 0; k < 2; ++k) {
      if (k >= n) continue;
      const float root = k == 0 ? r0 : r1;
      const vec3 x = origin + root * direction;
      const float h = dot(x - s.p0, axis);
      // (At most two crossings of a convex capsule; four bounds float's borderline cases.)
      if ((end == 0 ? h > len : h < 0.0) && candidates < 4) {
        for (int j = 0; j < 4; ++j)
          if (j == candidates) {
            candidate_t[j] = root;
            candidate_n[j] = x - centre;
          }
        ++candidates;
      }
    }
  }
  // Keep crossings outside the neighbours' capsules, in distance order.
  for (int k = 0; k < 4; ++k) {
    if (k >= candidates) continue;
    const vec3 x = origin + candidate_t[k] * direction;
    if (capsule_in_neighbour(s, x, candidate_t[k], extent)) continue;
    // Its place: after every crossing kept so far with t' <= t; from the back, so each slot
    // reads its neighbour before that one is overwritten.
    int at = 0;
    for (int j = 0; j < 4; ++j)
      if (j < count && t[j] <= candidate_t[k]) at = j + 1;
    const vec3 n_k = normalize(candidate_n[k]);
    const float u_k = len > 0.0 ? clamp(dot(x - s.p0, axis) / len, 0.0, 1.0) : 0.0;
    for (int j = 3; j >= 0; --j) {
      if (j > at && j <= count) {
        t[j] = t[j - 1];
        normal[j] = normal[j - 1];
        u[j] = u[j - 1];
      } else if (j == at) {
        t[j] = candidate_t[k];
        normal[j] = n_k;
        u[j] = u_k;
      }
    }
    ++count;
  }
  return count;
}

// One candidate of capsule_front_crossing, in capsule_crossings' order: taken when it is a
// crossing there, ahead of the eye (t + origin_t > 0), entering the capsule and strictly nearer
// than the one taken so far (capsule_crossings' stable order keeps the first of equal ones).
void capsule_take_front(CapsuleSegment s, vec3 origin, vec3 direction, float origin_t,
                        float extent, float len, vec3 axis, float root, vec3 outward,
                        inout bool found, inout float t, inout vec3 normal, inout float u) {
  if (found && !(root < t)) return;
  const vec3 x = origin + root * direction;
  const vec3 n = normalize(outward);
  if (root + origin_t <= 0.0 || dot(n, direction) >= 0.0) return;
  if (capsule_in_neighbour(s, x, root, extent)) return;
  found = true;
  t = root;
  normal = n;
  u = len > 0.0 ? clamp(dot(x - s.p0, axis) / len, 0.0, 1.0) : 0.0;
}

// The nearest crossing where the ray enters the surface `s` owns, ahead of the eye, which lies
// origin_t before `origin` along the ray: the first of capsule_crossings' list with t + origin_t
// > 0 and a normal against the ray, the crossing tiles composites. Only the smaller root of
// each quadratic can enter (its derivative, dot(normal, direction), is negative), so this takes
// those in one pass, without capsule_crossings' sorted lists or the neighbour tests of the
// other roots; on lavapipe the whole list cost about half the composite's hit computations.
bool capsule_front_crossing(CapsuleSegment s, vec3 origin, vec3 direction, float origin_t,
                            out float t, out vec3 normal, out float u) {
  t = 0.0, normal = vec3(0.0), u = 0.0;
  bool found = false;
  const float r = s.radius;
  const float extent = length(origin - s.p0);
  const vec3 axis_vector = s.p1 - s.p0;
  const float len = length(axis_vector);
  const vec3 axis = len > 0.0 ? axis_vector / len : vec3(0.0);
  float r0, r1;
  // The cylinder between the end planes.
  if (len > 0.0) {
    vec3 w_perp, d_perp;
    if (capsule_cylinder_roots(s, origin, direction, axis, r0, r1, w_perp, d_perp) > 0) {
      const float h = dot(origin - s.p0 + r0 * direction, axis);
      if (h >= 0.0 && h <= len)
        capsule_take_front(s, origin, direction, origin_t, extent, len, axis, r0,
                           w_perp + r0 * d_perp, found, t, normal, u);
    }
  }
  // The end sphere beyond p1; the start sphere only on a line's first segment.
  for (int end = 0; end < 2; ++end) {
    if (end == 1 && (s.flags & 1u) != 0u) break;
    const vec3 centre = end == 0 ? s.p1 : s.p0;
    if (capsule_sphere_roots(centre, r, origin, direction, r0, r1) == 0) continue;
    const vec3 x = origin + r0 * direction;
    const float h = dot(x - s.p0, axis);
    if (end == 0 ? h > len : h < 0.0)
      capsule_take_front(s, origin, direction, origin_t, extent, len, axis, r0, x - centre, found,
                         t, normal, u);
  }
  return found;
}
