#pragma once
// Transfer function for direct volume rendering: piecewise-linear RGB and
// opacity over the scalar value; opacity per "unit distance" as in
// VTK/ParaView (a segment of length s gets 1 - (1 - a)^(s / unit)).

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "../error.hpp"

namespace cellray {

struct TransferFunction {
  /// Strictly increasing control values; rgba[i] applies at values[i]; the
  /// ends extend flat. RGB and alpha in [0, 1].
  std::vector<float> values;
  std::vector<glm::vec4> rgba;
  /// World-space length over which opacity `a` accumulates to `a`.
  float unit_distance = 1.f;

  /// Colour and opacity at `v`; NaN values are fully transparent.
  glm::vec4 operator()(float v) const {
    if (!(v == v) || values.empty()) return glm::vec4(0.f);
    if (v <= values.front()) return rgba.front();
    if (v >= values.back()) return rgba.back();
    size_t const i = size_t(std::upper_bound(values.begin(), values.end(), v) - values.begin());
    float const t = (v - values[i - 1]) / (values[i] - values[i - 1]);
    return rgba[i - 1] + t * (rgba[i] - rgba[i - 1]);
  }

  /// Largest opacity anywhere on [lo, hi] (piecewise linear: attained at an
  /// end or a control point). Empty-space skipping drops a subtree when 0.
  float max_alpha(float lo, float hi) const {
    if (!(lo <= hi) || values.empty()) return 0.f;
    float a = std::max((*this)(lo).a, (*this)(hi).a);
    for (size_t i = 0; i < values.size(); ++i)
      if (values[i] > lo && values[i] < hi) a = std::max(a, rgba[i].a);
    return a;
  }

  /// @throws InvalidArgument naming the problem (sizes, order, ranges).
  void check() const {
    if (values.empty() || values.size() != rgba.size())
      throw InvalidArgument("transfer function needs as many colours as control values, at least one");
    for (size_t i = 1; i < values.size(); ++i)
      if (!(values[i] > values[i - 1]))
        throw InvalidArgument("transfer function control values must increase (at index " + std::to_string(i) + ")");
    for (auto const& c : rgba)
      for (int k = 0; k < 4; ++k)
        if (!(c[k] >= 0.f && c[k] <= 1.f)) throw InvalidArgument("transfer function colours must lie in [0, 1]");
    if (!(unit_distance > 0.f) || !std::isfinite(unit_distance))
      throw InvalidArgument("transfer function unit distance must be positive");
  }
};

/// Built-in colour maps, spread over [vmin, vmax]; opacity 0 on the lower
/// two thirds of the range, rising to `max_alpha` at vmax (a third of the
/// range is visible). Names: "cool-warm", "viridis", "inferno", "grayscale".
/// @throws InvalidArgument naming the presets for an unknown name.
inline TransferFunction transfer_function_preset(std::string_view name, float vmin, float vmax,
                                                 float max_alpha = 0.8f) {
  struct Stop {
    float t, r, g, b;
  };
  std::vector<Stop> stops;
  if (name == "cool-warm")  // Moreland's diverging map, as in ParaView
    stops = {{0.f, .230f, .299f, .754f}, {.25f, .484f, .636f, .980f}, {.5f, .865f, .865f, .865f},
             {.75f, .968f, .588f, .465f}, {1.f, .706f, .016f, .150f}};
  else if (name == "viridis")
    stops = {{0.f, .267f, .005f, .329f}, {.25f, .229f, .322f, .546f}, {.5f, .128f, .567f, .551f},
             {.75f, .369f, .789f, .383f}, {1.f, .993f, .906f, .144f}};
  else if (name == "inferno")
    stops = {{0.f, .001f, .000f, .014f}, {.25f, .341f, .062f, .429f}, {.5f, .735f, .216f, .330f},
             {.75f, .978f, .557f, .035f}, {1.f, .988f, .998f, .645f}};
  else if (name == "grayscale")
    stops = {{0.f, 0.f, 0.f, 0.f}, {1.f, 1.f, 1.f, 1.f}};
  else
    throw InvalidArgument("unknown transfer function preset '" + std::string(name) +
                          "' (presets: cool-warm, viridis, inferno, grayscale)");
  if (!(vmax > vmin)) {  // a constant field: a span that does not vanish in rounding (+1 does near 1e8)
    float const pad = std::max(1.f, std::fabs(vmin) * 1e-5f);
    if (vmin < std::numeric_limits<float>::max() - pad) vmax = vmin + pad;
    else vmin = vmax - pad;
  }
  TransferFunction tf;
  auto alpha = [&](float t) { return t <= 2.f / 3.f ? 0.f : max_alpha * (t - 2.f / 3.f) * 3.f; };
  std::vector<float> ts;
  for (auto const& s : stops) ts.push_back(s.t);
  ts.push_back(2.f / 3.f);
  std::sort(ts.begin(), ts.end());
  for (float t : ts) {
    auto it = std::lower_bound(stops.begin(), stops.end(), t, [](Stop const& s, float x) { return s.t < x; });
    Stop c = *it;
    if (it->t != t) {  // interpolate the colour at an inserted opacity knot
      Stop const& a = *(it - 1);
      float const u = (t - a.t) / (it->t - a.t);
      c = {t, a.r + u * (it->r - a.r), a.g + u * (it->g - a.g), a.b + u * (it->b - a.b)};
    }
    tf.values.push_back(float(double(vmin) + double(t) * (double(vmax) - double(vmin))));  // no overflow near +-3e38
    tf.rgba.emplace_back(c.r, c.g, c.b, alpha(t));
  }
  return tf;
}

/// A colour map (a transfer function's RGB; alpha ignored) as a table the
/// renderer's ISA units read as plain data: entry (v - lo) * scale, linear
/// between entries, clamped at the ends. Caps of clip planes and isosurfaces
/// coloured by another array use it.
struct ColorTable {
  static constexpr int entries = 1024;
  float lo = 0.f, scale = 0.f;
  float rgb[entries][3] = {};

  /// The table of `tf`'s colours; `fallback` everywhere when `tf` is empty.
  static ColorTable of(TransferFunction const& tf, glm::vec3 const& fallback) {
    ColorTable t;
    if (tf.values.empty()) {
      for (auto& e : t.rgb) e[0] = fallback.r, e[1] = fallback.g, e[2] = fallback.b;
      return t;
    }
    double const lo = tf.values.front(), hi = tf.values.size() > 1 ? tf.values.back() : lo + 1.0;
    t.lo = float(lo);
    t.scale = float(double(entries - 1) / (hi - lo));
    for (int i = 0; i < entries; ++i) {
      glm::vec4 const e = tf(float(lo + (hi - lo) * double(i) / double(entries - 1)));
      t.rgb[i][0] = e.r, t.rgb[i][1] = e.g, t.rgb[i][2] = e.b;
    }
    return t;
  }
};

}  // namespace cellray
