// MBOIT's moments and the transmittance reconstructed from them (Muenstermann et al. 2018;
// techniques.md section 6), for 4, 6 or 8 power moments or 2, 3 or 4 trigonometric moments.
//
// One general algorithm serves all six settings: with m = kMoments / 2, the (m+1) x (m+1) moment
// matrix (Hankel b_{i+j} for power moments, Hermitian Toeplitz b_{i-j} for trigonometric ones)
// is factored as L D L^H, solved for the kernel polynomial through the fragment's depth, and the
// polynomial's m roots (Durand-Kerner iteration) are the other support points of the canonical
// representation. Interpolating the weights (beta at the fragment, 1 in front, 0 behind) through
// the m + 1 points in Newton form and pairing the result with the moments gives the absorbance in
// front of the fragment.
//
// Storage (floats per pixel): b0 b1 b2 b3 in target 0, the last moment b_n in target 1 (R32F),
// and b4 .. b_{n-1} in target 2 when n > 4. Trigonometric moment k is stored as (Re, Im) in
// floats 2k - 1 and 2k.

layout(constant_id = 0) const uint kTrigonometric = 0;  // 0: power moments, 1: trigonometric
layout(constant_id = 1) const uint kMoments = 4;        // real values beyond b0: 4, 6 or 8

const int kMaxOrder = 4;  // m = kMoments / 2

// Float j (0 .. kMoments) of a pixel in the copies of the moment targets (binding 2).
uint moment_word(uint j, uint pixel, uint pixels) {
  if (j < 4u) return 4u * pixel + j;
  if (j == kMoments) return 4u * pixels + pixel;
  return 5u * pixels + 4u * pixel + (j - 4u);
}

// Floats of the moment targets' copies: where the second pass's accumulation follows them.
uint moment_floats(uint pixels) {
  return (kMoments > 4u ? 9u : 5u) * pixels;
}

// The trigonometric phase of warped depth z in [-1, 1]: [0, 2 pi - wrapping zone angle].
vec2 circle_point(float z) {
  const float phase = frame.moment_params.x * (z + 1.0);
  return vec2(cos(phase), sin(phase));
}

// The moment vector (b0 .. b_n) of one fragment with absorbance q at warped depth z.
void fragment_moments(float q, float z, out float v[9]) {
  v[0] = q;
  for (int j = 1; j < 9; ++j) v[j] = 0.0;
  if (kTrigonometric != 0u) {
    const vec2 w = circle_point(z);
    vec2 wk = w;
    for (uint k = 1u; 2u * k <= kMoments; ++k) {
      v[2u * k - 1u] = q * wk.x;
      v[2u * k] = q * wk.y;
      wk = vec2(wk.x * w.x - wk.y * w.y, wk.x * w.y + wk.y * w.x);
    }
  } else {
    float zj = q;
    for (uint j = 1u; j <= kMoments; ++j) {
      zj *= z;
      v[j] = zj;
    }
  }
}

vec2 cmul(vec2 a, vec2 b) {
  return vec2(a.x * b.x - a.y * b.y, a.x * b.y + a.y * b.x);
}
vec2 cconj(vec2 a) {
  return vec2(a.x, -a.y);
}
vec2 cdiv(vec2 a, vec2 b) {
  return cmul(a, cconj(b)) / dot(b, b);
}

// Monotonic along the circle from angle 0 (not arc length): compares positions on the circle.
float circle_parameter(vec2 p) {
  float r = abs(p.y) - abs(p.x);
  if (p.x < 0.0) r = 2.0 - r;
  if (p.y < 0.0) r = 6.0 - r;
  return r;
}

// The power moments' bias vectors (toward a well-conditioned distribution; floats 1 .. n).
float power_bias_target(uint j) {
  if ((j & 1u) == 1u) return 0.0;
  if (kMoments == 4u) return 0.375;
  if (kMoments == 6u) return j == 2u ? 0.48 : (j == 4u ? 0.451 : 0.45);
  return j == 2u ? 0.75 : (j == 4u ? 0.67666666666666664 : (j == 6u ? 0.63 : 0.60030303030303034));
}

// Transmittance in front of warped depth zf from the moments v (b0 .. b_n, not normalised).
float moment_transmittance(float v[9], float zf) {
  const float bias = frame.oit_params.x, beta = frame.oit_params.y;
  const int m = int(kMoments) / 2;
  const float b0 = v[0];
  const bool trig = kTrigonometric != 0u;
  // Normalised, biased moments as complex numbers: power b[0 .. n], trigonometric b[0 .. m].
  vec2 b[9];
  b[0] = vec2(1.0, 0.0);
  for (uint j = 1u; j <= kMoments; ++j) {
    if (trig) {
      if (2u * j <= kMoments)
        b[j] = (1.0 - bias) * vec2(v[2u * j - 1u], v[2u * j]) / b0;
    } else {
      b[j] = vec2(mix(v[j] / b0, power_bias_target(j), bias), 0.0);
    }
  }
  // L D L^H of the moment matrix A (i, j).
  vec2 l[kMaxOrder + 1][kMaxOrder + 1];
  float d[kMaxOrder + 1];
  for (int j = 0; j <= m; ++j) {
    vec2 s = trig ? b[0] : b[2 * j];
    for (int k = 0; k < j; ++k) s -= d[k] * cmul(l[j][k], cconj(l[j][k]));
    d[j] = s.x;
    for (int i = j + 1; i <= m; ++i) {
      vec2 t = trig ? b[i - j] : b[i + j];
      for (int k = 0; k < j; ++k) t -= d[k] * cmul(l[i][k], cconj(l[j][k]));
      l[i][j] = t / d[j];
    }
  }
  // Solve A c = (1, w, .., w^m) for the kernel polynomial through the fragment's point w.
  const vec2 w = trig ? circle_point(zf) : vec2(zf, 0.0);
  vec2 c[kMaxOrder + 1];
  c[0] = vec2(1.0, 0.0);
  for (int i = 1; i <= m; ++i) c[i] = cmul(c[i - 1], w);
  for (int i = 1; i <= m; ++i)
    for (int k = 0; k < i; ++k) c[i] -= cmul(l[i][k], c[k]);
  for (int i = 0; i <= m; ++i) c[i] /= d[i];
  for (int i = m - 1; i >= 0; --i)
    for (int k = i + 1; k <= m; ++k) c[i] -= cmul(cconj(l[k][i]), c[k]);
  // Roots of sum conj(c_j) x^j: Durand-Kerner on the monic polynomial. When the fragment's
  // depth is itself a support point the leading coefficient can vanish (a root at infinity,
  // weight 0): keep it just above zero so that root lands far away instead of dividing by 0.
  float largest = 0.0;
  for (int j = 0; j <= m; ++j) largest = max(largest, length(c[j]));
  const float leading = length(c[m]), floor_leading = 1e-7 * largest;
  const vec2 top = leading >= floor_leading
                       ? c[m]
                       : (leading > 0.0 ? c[m] / leading : vec2(1.0, 0.0)) * floor_leading;
  vec2 a[kMaxOrder];
  for (int j = 0; j < m; ++j) a[j] = cdiv(cconj(c[j]), cconj(top));
  vec2 z[kMaxOrder + 1];  // z[0] = w, z[1 .. m] = roots
  z[0] = w;
  vec2 seed = vec2(1.0, 0.0);
  for (int i = 1; i <= m; ++i) {
    z[i] = seed;
    seed = cmul(seed, vec2(0.4, 0.9));
  }
  for (int iteration = 0; iteration < 64; ++iteration) {
    float change = 0.0;
    for (int i = 1; i <= m; ++i) {
      vec2 p = vec2(1.0, 0.0);
      for (int j = m - 1; j >= 0; --j) p = cmul(p, z[i]) + a[j];
      vec2 q = vec2(1.0, 0.0);
      for (int j = 1; j <= m; ++j)
        if (j != i) q = cmul(q, z[i] - z[j]);
      const vec2 delta = cdiv(p, q);
      z[i] -= delta;
      change = max(change, length(delta) / max(1.0, length(z[i])));
    }
    if (change < 1e-6) break;
  }
  // Weights: beta at the fragment, 1 for support points in front of it, 0 behind (for
  // trigonometric moments a linear ramp across the wrapping zone).
  vec2 dd[kMaxOrder + 1];
  dd[0] = vec2(beta, 0.0);
  const float depth_parameter = circle_parameter(w);
  for (int i = 1; i <= m; ++i) {
    float f;
    if (trig) {
      const float root_parameter = circle_parameter(normalize(z[i]));
      f = (root_parameter < depth_parameter ? 1.0 : 0.0) +
          clamp(root_parameter * frame.moment_params.y + frame.moment_params.z, 0.0, 1.0);
    } else {
      f = z[i].x < zf ? 1.0 : 0.0;
    }
    dd[i] = vec2(f, 0.0);
  }
  // Newton divided differences, then the interpolating polynomial's monomial coefficients.
  for (int level = 1; level <= m; ++level)
    for (int i = m; i >= level; --i) dd[i] = cdiv(dd[i] - dd[i - 1], z[i] - z[i - level]);
  vec2 poly[kMaxOrder + 1];
  for (int j = 0; j <= m; ++j) poly[j] = vec2(0.0);
  poly[0] = dd[m];
  for (int k = m - 1; k >= 0; --k) {
    for (int j = m; j >= 1; --j) poly[j] = poly[j - 1] - cmul(z[k], poly[j]);
    poly[0] = dd[k] - cmul(z[k], poly[0]);
  }
  float absorbance = 0.0;
  for (int j = 0; j <= m; ++j) absorbance += cmul(b[j], poly[j]).x;
  return clamp(exp(-b0 * absorbance), 0.0, 1.0);
}
