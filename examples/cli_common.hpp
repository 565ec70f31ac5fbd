#pragma once
// What the example command-line programs share (cellray-render and
// cellray-mpi-render): exit codes, usage errors, the parsing of numeric
// flags and the isosurface palette -- one copy, so the two programs read
// flags alike and draw the same picture.

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

namespace cellray_cli {

using Clock = std::chrono::steady_clock;

/// Exit codes, documented in --help and docs/cli.md.
enum ExitCode { exit_ok = 0, exit_other = 1, exit_usage = 2, exit_io = 3, exit_invalid_mesh = 4 };

/// A bad flag or flag value found after parsing (exit 2).
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// A name from the command line or a file, shortened for messages (a 100 KB
/// --array name must not become a 100 KB error line).
inline std::string shown(std::string const& name) { return name.size() <= 80 ? name : name.substr(0, 77) + "..."; }

inline double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

inline std::vector<std::string> split(std::string const& text, char sep) {
  std::vector<std::string> out;
  std::string item;
  std::istringstream s(text);
  while (std::getline(s, item, sep)) out.push_back(item);
  if (!text.empty() && text.back() == sep) out.emplace_back();
  return out;
}

inline float parse_float(std::string const& text, std::string const& flag) {
  size_t used = 0;
  float v = 0.f;
  try {
    v = std::stof(text, &used);
  } catch (std::exception const&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || !std::isfinite(v))
    throw UsageError(flag + ": '" + text + "' is not a finite number");
  return v;
}

/// A float flag's check: a finite number in [lo, hi]. CLI11's Range lets
/// NaN through (every comparison with it is false), and `--opacity nan`
/// rendered with the default opacity instead of failing.
inline CLI::Validator finite_in(float lo, float hi) {
  char range[64];
  std::snprintf(range, sizeof range, "[%g, %g]", double(lo), double(hi));
  return CLI::Validator(
      [lo, hi, range = std::string(range)](std::string& text) -> std::string {
        char* end = nullptr;
        double const v = std::strtod(text.c_str(), &end);
        if (text.empty() || *end != '\0' || !(v >= double(lo) && v <= double(hi)))
          return "must be a number in " + range + ", got '" + shown(text) + "'";
        return "";
      },
      "FLOAT in " + std::string(range));
}

/// CLI11's PositiveNumber prints its range as 309 digits (and lets NaN
/// through); this says it plainly.
inline CLI::Validator const positive_finite(
    [](std::string& text) -> std::string {
      char* end = nullptr;
      double const v = std::strtod(text.c_str(), &end);
      if (text.empty() || *end != '\0' || !(v > 0.0) || !(v <= double(std::numeric_limits<float>::max())))
        return "must be a positive finite number, got '" + shown(text) + "'";
      return "";
    },
    "POSITIVE");

inline std::vector<float> parse_floats(std::string const& text, std::string const& flag) {
  std::vector<float> out;
  for (auto const& item : split(text, ',')) out.push_back(parse_float(item, flag));
  if (out.empty()) throw UsageError(flag + ": expected a comma-separated list of numbers");
  return out;
}

inline glm::vec3 parse_vec3(std::string const& text, std::string const& flag) {
  auto const v = parse_floats(text, flag);
  if (v.size() != 3) throw UsageError(flag + ": expected X,Y,Z, got '" + text + "'");
  return {v[0], v[1], v[2]};
}

/// "WxH", both in [1, 32768] (a 32768^2 float RGBA image is already 16 GiB).
inline void parse_size(std::string const& text, int& w, int& h) {
  auto const x = text.find('x');
  auto bad = [&] { return UsageError("--size: expected WxH with both in [1, 32768], got '" + text + "'"); };
  if (x == std::string::npos) throw bad();
  try {
    size_t uw = 0, uh = 0;
    std::string const sw = text.substr(0, x), sh = text.substr(x + 1);
    long const lw = std::stol(sw, &uw), lh = std::stol(sh, &uh);
    if (uw != sw.size() || uh != sh.size() || lw < 1 || lh < 1 || lw > 32768 || lh > 32768) throw bad();
    w = int(lw);
    h = int(lh);
  } catch (UsageError const&) {
    throw;
  } catch (std::exception const&) {
    throw bad();
  }
}

/// "R,G,B", "R,G,B,A" in [0, 1], or white, black, transparent.
inline glm::vec4 parse_background(std::string const& text) {
  if (text == "white") return {1.f, 1.f, 1.f, 1.f};
  if (text == "black") return {0.f, 0.f, 0.f, 1.f};
  if (text == "transparent") return {0.f, 0.f, 0.f, 0.f};
  auto const v = parse_floats(text, "--background");
  if (v.size() != 3 && v.size() != 4)
    throw UsageError("--background: expected R,G,B or R,G,B,A in [0, 1], or white, black, transparent");
  for (float c : v)
    if (c < 0.f || c > 1.f) throw UsageError("--background: components must lie in [0, 1], got '" + text + "'");
  return {v[0], v[1], v[2], v.size() == 4 ? v[3] : 1.f};
}

/// A pleasant fixed palette, by isovalue index.
inline glm::vec3 iso_color(size_t i) {
  static glm::vec3 const palette[] = {{0.31f, 0.57f, 0.85f}, {0.96f, 0.62f, 0.25f}, {0.85f, 0.33f, 0.35f},
                                      {0.42f, 0.75f, 0.45f}, {0.65f, 0.50f, 0.80f}, {0.95f, 0.85f, 0.35f},
                                      {0.45f, 0.80f, 0.82f}, {0.80f, 0.55f, 0.45f}};
  return palette[i % (sizeof(palette) / sizeof(palette[0]))];
}

}  // namespace cellray_cli
