#pragma once
// Deterministic random numbers and procedural noise for the synthetic scene.
// Everything is integer-hashed so results are identical on every platform and
// independent of thread scheduling (no std:: distributions, whose output is
// implementation-defined).
#include <algorithm>
#include <cmath>
#include <cstdint>

namespace strata::synthetic {

inline std::uint64_t mix64(std::uint64_t z) {  // SplitMix64 finaliser (Steele et al. 2014)
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// A small sequential generator (SplitMix64) for scene layout and camera paths.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : state_(mix64(seed + 0x9E3779B97F4A7C15ull)) {}
  std::uint64_t next() {
    state_ += 0x9E3779B97F4A7C15ull;
    return mix64(state_);
  }
  double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }  // [0,1)
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  double normal() {  // Box-Muller
    const double u1 = std::max(uniform(), 1e-300), u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
  }

 private:
  std::uint64_t state_;
};

// Lattice hash (MurmurHash3's 32-bit finaliser over a linear mix): cheap enough
// for per-texel noise, and well distributed for visual purposes.
inline std::uint32_t hash2(std::int64_t x, std::int64_t y, std::uint32_t seed) {
  std::uint32_t h = std::uint32_t(x) * 0x8DA6B343u ^ std::uint32_t(y) * 0xD8163841u ^ seed * 0xCB1AB31Fu;
  h ^= h >> 16;
  h *= 0x85EBCA6Bu;
  h ^= h >> 13;
  h *= 0xC2B2AE35u;
  h ^= h >> 16;
  return h;
}
inline double hash_unit(std::int64_t x, std::int64_t y, std::uint32_t seed) {  // [0,1)
  return double(hash2(x, y, seed)) * (1.0 / 4294967296.0);
}

inline double smooth5(double t) { return t * t * t * (t * (t * 6 - 15) + 10); }  // quintic fade
inline double smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

// Value noise on the unit lattice, in [-1, 1].
inline double value_noise(double x, double y, std::uint32_t seed) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = std::int64_t(fx), iy = std::int64_t(fy);
  const double u = smooth5(x - fx), v = smooth5(y - fy);
  const double a = hash_unit(ix, iy, seed), b = hash_unit(ix + 1, iy, seed);
  const double c = hash_unit(ix, iy + 1, seed), d = hash_unit(ix + 1, iy + 1, seed);
  return 2.0 * (a + (b - a) * u + (c - a) * v + (a - b - c + d) * u * v) - 1.0;
}

// Fractal sum of value noise from `longest` wavelength (metres) down, halving each
// octave. Octaves shorter than the footprint (metres per pixel or texel) fade out,
// which band-limits the texture: no aliasing however far the camera is.
inline double fbm(double x, double y, double longest, int octaves, double footprint,
                  std::uint32_t seed, double gain = 0.55) {
  double sum = 0, norm = 0, amp = 1, wavelength = longest;
  for (int o = 0; o < octaves; ++o) {
    const double w = std::clamp(wavelength / std::max(footprint, 1e-9) - 1.0, 0.0, 1.0);
    norm += amp;
    if (w <= 0) break;
    sum += w * amp * value_noise(x / wavelength, y / wavelength, seed + 101u * std::uint32_t(o));
    amp *= gain;
    wavelength *= 0.5;
  }
  return norm > 0 ? sum / norm * 1.6 : 0.0;  // 1.6: brings the usual range near [-1, 1]
}

// Scattered round clasts (pebbles, gravel, flecks) on a jittered lattice of
// `cell` metres: at most one clast per cell, present with probability `density`,
// radius between rmin and rmax (metres). Returns the clast under (x, y) if any.
struct Clast {
  double coverage = 0;  // 0..1, antialiased over the footprint
  double height = 0;    // metres above the surrounding surface (a flattened dome)
  double tone = 0;      // 0..1, picks the clast's colour
};
inline Clast clast_at(double x, double y, double cell, double density, double rmin, double rmax,
                      double footprint, std::uint32_t seed) {
  Clast best;
  const auto cx = std::int64_t(std::floor(x / cell)), cy = std::int64_t(std::floor(y / cell));
  for (std::int64_t j = cy - 1; j <= cy + 1; ++j) {
    for (std::int64_t i = cx - 1; i <= cx + 1; ++i) {
      if (hash_unit(i, j, seed) >= density) continue;
      const double px = (double(i) + hash_unit(i, j, seed + 1)) * cell;
      const double py = (double(j) + hash_unit(i, j, seed + 2)) * cell;
      const double r = rmin + (rmax - rmin) * hash_unit(i, j, seed + 3);
      const double dx = x - px, dy = y - py;
      if (dx * dx + dy * dy > (r + footprint) * (r + footprint)) continue;  // before any trigonometry
      // Slightly elongated: scale one axis by up to 1.5 along a random direction.
      const double ang = 6.283185307179586 * hash_unit(i, j, seed + 4);
      const double ca = std::cos(ang), sa = std::sin(ang);
      const double a = ca * dx + sa * dy, b = (-sa * dx + ca * dy) * (1.0 + 0.5 * hash_unit(i, j, seed + 5));
      const double d = std::sqrt(a * a + b * b);
      if (d > r + footprint) continue;
      const double cov = smoothstep(r + 0.5 * footprint, r - 0.5 * footprint, d);
      if (cov > best.coverage) {
        best.coverage = cov;
        const double s = std::clamp(1.0 - (d * d) / (r * r), 0.0, 1.0);
        best.height = 0.45 * r * std::sqrt(s);
        best.tone = hash_unit(i, j, seed + 6);
      }
    }
  }
  return best;
}

}  // namespace strata::synthetic
