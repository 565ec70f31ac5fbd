#pragma once
// cellray-render's colour legend and title, drawn into a rendered image: a
// vertical scalar bar at the right (ParaView's "scalar bar": the array's
// name above, 3-5 labelled ticks on the value range at its left), for DVR
// filled with the transfer function's colours, for isosurfaces marked with
// each surface's colour at its isovalue plus a labelled swatch; and a title
// centred at the top. Text by stb_truetype from a TrueType file. Everything
// is composited "over" the image in straight alpha, so it works on opaque
// and transparent backgrounds alike; text carries a halo of the opposite
// shade, so it reads over the mesh too.
//
// Include in one translation unit only: it compiles stb_truetype's
// implementation (static functions).

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <string_view>
#include <vector>

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include <cellray/error.hpp>
#include <cellray/io/detail.hpp>
#include <cellray/render/image.hpp>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wcast-qual"
#define STBTT_STATIC
#define STB_TRUETYPE_IMPLEMENTATION
#include <stb/stb_truetype.h>
#pragma GCC diagnostic pop

namespace cellray_render {

/// The font cellray-render uses unless --font says otherwise (Debian's
/// fonts-dejavu-core, installed by scripts/install-deps.sh).
inline constexpr char const* default_font_path = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

/// Code points of UTF-8 text; a malformed byte becomes U+FFFD.
inline std::vector<int> utf8_codepoints(std::string_view s) {
  std::vector<int> out;
  for (size_t i = 0; i < s.size();) {
    unsigned char const c = static_cast<unsigned char>(s[i]);
    int n = c < 0x80 ? 0 : (c >> 5) == 6 ? 1 : (c >> 4) == 14 ? 2 : (c >> 3) == 30 ? 3 : -1;
    int cp = n == 0 ? c : n == 1 ? c & 0x1f : n == 2 ? c & 0x0f : c & 0x07;
    bool ok = n >= 0;
    for (int k = 1; ok && k <= n; ++k) {
      if (i + size_t(k) >= s.size() || (static_cast<unsigned char>(s[i + size_t(k)]) >> 6) != 2) {
        ok = false;
        break;
      }
      cp = (cp << 6) | (static_cast<unsigned char>(s[i + size_t(k)]) & 0x3f);
    }
    out.push_back(ok ? cp : 0xfffd);
    i += ok ? size_t(n) + 1 : 1;
  }
  return out;
}

/// A TrueType font read whole into memory.
class Font {
 public:
  /// @throws cellray::IoError naming `path` when it is missing, unreadable
  ///         or not a TrueType font.
  explicit Font(std::string path) : path_(std::move(path)) {
    // Not a FIFO or a device (`--font /dev/zero` read forever) or a directory.
    try {
      cellray::io::require_regular_file(path_, "font file");
    } catch (cellray::IoError const& e) {
      throw cellray::IoError(std::string("font file ") + e.what() + " (Debian: fonts-dejavu-core; --font FILE)");
    }
    std::ifstream in(path_, std::ios::binary);
    if (!in) throw cellray::IoError("font file " + path_ + " missing or unreadable (Debian: fonts-dejavu-core; --font FILE)");
    data_.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    int const offset = data_.empty() ? -1 : stbtt_GetFontOffsetForIndex(data_.data(), 0);
    if (offset < 0 || !stbtt_InitFont(&info_, data_.data(), offset))
      throw cellray::IoError("font file " + path_ + ": not a TrueType font");
    stbtt_GetFontVMetrics(&info_, &ascent_, &descent_, &line_gap_);
  }
  Font(Font const&) = delete;  // info_ points into data_
  Font& operator=(Font const&) = delete;

  float scale(float px) const { return stbtt_ScaleForPixelHeight(&info_, px); }
  float ascent(float px) const { return float(ascent_) * scale(px); }
  float descent(float px) const { return -float(descent_) * scale(px); }  ///< positive, below the baseline

  /// Advance width of `text` at `px` pixels, kerning included.
  float width(std::string_view text, float px) const {
    auto const cps = utf8_codepoints(text);
    float const s = scale(px);
    float w = 0.f;
    for (size_t i = 0; i < cps.size(); ++i) {
      int adv = 0, lsb = 0;
      stbtt_GetCodepointHMetrics(&info_, cps[i], &adv, &lsb);
      w += float(adv) * s;
      if (i + 1 < cps.size()) w += float(stbtt_GetCodepointKernAdvance(&info_, cps[i], cps[i + 1])) * s;
    }
    return w;
  }

  /// `text` cut to at most `max_width` pixels, ending "..." when cut.
  std::string fit(std::string const& text, float px, float max_width) const {
    if (width(text, px) <= max_width) return text;
    // The longest prefix whose width with "..." fits, each prefix's width
    // summed as width() sums it: one pass (measuring every prefix anew took
    // over a minute on a 100 KB title).
    auto const cps = utf8_codepoints(text);
    float const s = scale(px);
    int const dot = '.';
    int dot_adv = 0, lsb = 0;
    stbtt_GetCodepointHMetrics(&info_, dot, &dot_adv, &lsb);
    float const dot_kern = float(stbtt_GetCodepointKernAdvance(&info_, dot, dot)) * s;
    auto with_dots = [&](float w) {
      for (int d = 0; d < 3; ++d) {
        w += float(dot_adv) * s;
        if (d < 2) w += dot_kern;
      }
      return w;
    };
    size_t keep = 0;
    bool fits = with_dots(0.f) <= max_width;
    float w = 0.f;  // width of cps[0, k)
    for (size_t k = 1; k < cps.size(); ++k) {
      int adv = 0;
      stbtt_GetCodepointHMetrics(&info_, cps[k - 1], &adv, &lsb);
      w += float(adv) * s;
      if (with_dots(w + float(stbtt_GetCodepointKernAdvance(&info_, cps[k - 1], dot)) * s) <= max_width) keep = k, fits = true;
      w += float(stbtt_GetCodepointKernAdvance(&info_, cps[k - 1], cps[k])) * s;
    }
    if (!fits) return "";
    std::string out;
    for (size_t i = 0; i < keep; ++i) append_utf8(out, cps[i]);
    return out + "...";
  }

  /// Coverage in [0, 1] of `text` in a w x h buffer, the pen starting at
  /// (pen_x, baseline): glyphs at sub-pixel x positions, overlaps merged by max.
  void coverage(std::string_view text, float px, float pen_x, float baseline, int w, int h,
                std::vector<float>& cov) const {
    cov.assign(size_t(w) * size_t(h), 0.f);
    auto const cps = utf8_codepoints(text);
    float const s = scale(px);
    float x = pen_x;
    std::vector<unsigned char> glyph;
    for (size_t i = 0; i < cps.size(); ++i) {
      float const fx = std::floor(x), sub = x - fx;
      int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
      stbtt_GetCodepointBitmapBoxSubpixel(&info_, cps[i], s, s, sub, 0.f, &x0, &y0, &x1, &y1);
      int const gw = x1 - x0, gh = y1 - y0;
      if (gw > 0 && gh > 0) {
        glyph.assign(size_t(gw) * size_t(gh), 0);
        stbtt_MakeCodepointBitmapSubpixel(&info_, glyph.data(), gw, gh, gw, s, s, sub, 0.f, cps[i]);
        int const bx = int(fx) + x0, by = int(std::lround(baseline)) + y0;
        for (int gy = 0; gy < gh; ++gy)
          for (int gx = 0; gx < gw; ++gx) {
            int const cx = bx + gx, cy = by + gy;
            if (cx < 0 || cy < 0 || cx >= w || cy >= h) continue;
            float& c = cov[size_t(cy) * size_t(w) + size_t(cx)];
            c = std::max(c, float(glyph[size_t(gy) * size_t(gw) + size_t(gx)]) / 255.f);
          }
      }
      int adv = 0, lsb = 0;
      stbtt_GetCodepointHMetrics(&info_, cps[i], &adv, &lsb);
      x += float(adv) * s;
      if (i + 1 < cps.size()) x += float(stbtt_GetCodepointKernAdvance(&info_, cps[i], cps[i + 1])) * s;
    }
  }

  static void append_utf8(std::string& out, int cp) {
    if (cp < 0x80) {
      out += char(cp);
    } else if (cp < 0x800) {
      out += char(0xc0 | (cp >> 6)), out += char(0x80 | (cp & 0x3f));
    } else if (cp < 0x10000) {
      out += char(0xe0 | (cp >> 12)), out += char(0x80 | ((cp >> 6) & 0x3f)), out += char(0x80 | (cp & 0x3f));
    } else {
      out += char(0xf0 | (cp >> 18)), out += char(0x80 | ((cp >> 12) & 0x3f));
      out += char(0x80 | ((cp >> 6) & 0x3f)), out += char(0x80 | (cp & 0x3f));
    }
  }

 private:
  std::string path_;
  std::vector<unsigned char> data_;
  stbtt_fontinfo info_{};
  int ascent_ = 0, descent_ = 0, line_gap_ = 0;
};

/// Composites colour `c` with opacity `a` over pixel (x, y), straight alpha
/// (Porter-Duff "over"); outside the image, nothing.
inline void blend(cellray::Image& img, int x, int y, glm::vec3 c, float a) {
  if (x < 0 || y < 0 || x >= img.width || y >= img.height || !(a > 0.f)) return;
  a = std::min(a, 1.f);
  float* p = img.pixel(x, y);
  float const da = std::clamp(p[3], 0.f, 1.f), oa = a + da * (1.f - a);
  for (int k = 0; k < 3; ++k) p[k] = (c[k] * a + p[k] * da * (1.f - a)) / oa;
  p[3] = oa;
}

/// Fills [x0, x1) x [y0, y1).
inline void fill_rect(cellray::Image& img, int x0, int y0, int x1, int y1, glm::vec3 c, float a = 1.f) {
  for (int y = std::max(y0, 0); y < std::min(y1, img.height); ++y)
    for (int x = std::max(x0, 0); x < std::min(x1, img.width); ++x) blend(img, x, y, c, a);
}

/// A 1-pixel frame just inside [x0, x1) x [y0, y1).
inline void frame_rect(cellray::Image& img, int x0, int y0, int x1, int y1, glm::vec3 c, float a = 1.f) {
  fill_rect(img, x0, y0, x1, y0 + 1, c, a);
  fill_rect(img, x0, y1 - 1, x1, y1, c, a);
  fill_rect(img, x0, y0 + 1, x0 + 1, y1 - 1, c, a);
  fill_rect(img, x1 - 1, y0 + 1, x1, y1 - 1, c, a);
}

/// Ink and halo colours that read on a background `bg` (straight RGBA):
/// dark text with a light halo on light or transparent backgrounds, light
/// text with a dark halo on dark ones.
struct Ink {
  glm::vec3 text, halo;
  explicit Ink(glm::vec4 bg) {
    float const lum = 0.2126f * bg.r + 0.7152f * bg.g + 0.0722f * bg.b;
    bool const light = bg.a < 0.5f || lum > 0.5f;
    text = light ? glm::vec3(0.08f) : glm::vec3(0.95f);
    halo = light ? glm::vec3(1.f) : glm::vec3(0.f);
  }
};

enum class Align { left, centre, right };

/// Draws `text` at `px` pixels with its baseline at `baseline`, aligned to
/// `x` as `align` says, with a halo of radius ~px/12 (at least 1 pixel).
inline void draw_text(cellray::Image& img, Font const& font, std::string const& text, float x, float baseline,
                      float px, Align align, Ink const& ink) {
  if (text.empty()) return;
  float const w = font.width(text, px);
  float const left = align == Align::left ? x : align == Align::centre ? x - 0.5f * w : x - w;
  int const r = std::max(1, int(std::lround(px / 12.f)));
  int const pad = r + 2;
  int const ox = int(std::floor(left)) - pad, oy = int(std::floor(baseline - font.ascent(px))) - pad;
  int const bw = int(std::ceil(w)) + 2 * pad + 2, bh = int(std::ceil(font.ascent(px) + font.descent(px))) + 2 * pad + 2;
  std::vector<float> cov, halo(size_t(bw) * size_t(bh), 0.f);
  font.coverage(text, px, left - float(ox), baseline - float(oy), bw, bh, cov);
  for (int y = 0; y < bh; ++y)
    for (int x2 = 0; x2 < bw; ++x2) {
      float m = 0.f;
      for (int dy = -r; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx) {
          int const sx = x2 + dx, sy = y + dy;
          if (sx >= 0 && sy >= 0 && sx < bw && sy < bh && dx * dx + dy * dy <= r * r + r)
            m = std::max(m, cov[size_t(sy) * size_t(bw) + size_t(sx)]);
        }
      halo[size_t(y) * size_t(bw) + size_t(x2)] = m;
    }
  for (int y = 0; y < bh; ++y)
    for (int x2 = 0; x2 < bw; ++x2) {
      size_t const i = size_t(y) * size_t(bw) + size_t(x2);
      blend(img, ox + x2, oy + y, ink.halo, 0.75f * halo[i]);
      blend(img, ox + x2, oy + y, ink.text, cov[i]);
    }
}

/// 3 to 5 round tick values inside [lo, hi] (steps 1, 2, 2.5, 5 x 10^k; the
/// most ticks, then the larger step); lo, the middle and hi when no round
/// step gives 3; {lo} when lo == hi.
inline std::vector<double> nice_ticks(double lo, double hi, double* step_out = nullptr) {
  if (!(hi > lo)) {
    if (step_out) *step_out = std::max(std::fabs(lo), 1.0);
    return {lo};
  }
  double const span = hi - lo;
  int const e0 = int(std::floor(std::log10(span)));
  std::vector<double> best;
  double best_step = 0;
  for (int e = e0 - 2; e <= e0 + 1; ++e)
    for (double m : {1.0, 2.0, 2.5, 5.0}) {
      double const step = m * std::pow(10.0, e);
      double const k0 = std::ceil(lo / step), k1 = std::floor(hi / step);
      double const count = k1 - k0 + 1;
      if (count < 3 || count > 5 || double(best.size()) > count) continue;
      if (double(best.size()) == count && step < best_step) continue;
      best.clear();
      for (double k = k0; k <= k1; ++k) best.push_back(std::fabs(k) < 0.5 ? 0.0 : k * step);
      best_step = step;
    }
  if (best.empty()) {
    best = {lo, lo + 0.5 * span, hi};
    best_step = 0.5 * span;
  }
  if (step_out) *step_out = best_step;
  return best;
}

/// A tick label: fixed decimals enough for `step`, or scientific notation
/// for magnitudes of a million and more or below 0.001.
inline std::string format_tick(double v, double step, double magnitude) {
  char s[64];
  if (magnitude >= 1e6 || (magnitude > 0 && magnitude < 1e-3)) {
    int const digits = std::clamp(int(std::ceil(std::log10(magnitude / step) - 1e-9)), 0, 6);
    std::snprintf(s, sizeof s, "%.*e", digits, v);
  } else {
    int const decimals = std::clamp(int(std::ceil(-std::log10(step) - 1e-9)), 0, 9);
    std::snprintf(s, sizeof s, "%.*f", decimals, v);
  }
  return s;
}

/// An isovalue's label: up to 6 significant digits.
inline std::string format_value(double v) {
  char s[64];
  std::snprintf(s, sizeof s, "%.6g", v);
  return s;
}

/// What the scalar bar shows; values in the file's units.
struct Legend {
  std::string name;                ///< the array's name, above the bar
  double lo = 0, hi = 1;           ///< the bar's ends (bottom, top)
  std::vector<glm::vec3> ramp;     ///< DVR: colours from lo to hi, evenly spaced; empty for isosurfaces
  struct Swatch {
    double value;
    glm::vec3 colour;
  };
  std::vector<Swatch> swatches;    ///< isosurfaces: colour at each isovalue
  glm::vec4 background{1.f};       ///< the render's background, to choose the ink
};

/// Base text size for a width x height image: 2.8% of the shorter side, at
/// least 8 pixels.
inline float legend_font_px(int width, int height) {
  return std::max(8.f, std::round(0.028f * float(std::min(width, height))));
}

/// Draws the scalar bar of `leg` at the right edge of `img`, vertically
/// centred, half the image's height.
inline void draw_legend(cellray::Image& img, Font const& font, Legend const& leg) {
  Ink const ink(leg.background);
  float const px = legend_font_px(img.width, img.height);
  int const margin = int(px), gap = std::max(2, int(px / 3)), tick = std::max(2, int(0.4f * px));
  int const bar_w = int(std::lround(1.1f * px)), bar_h = std::max(8, int(0.5f * float(img.height)));
  int const y0 = (img.height - bar_h) / 2 + int(px / 2), y1 = y0 + bar_h;

  double step = 1;
  auto const ticks = nice_ticks(leg.lo, leg.hi, &step);
  double const magnitude = std::max(std::fabs(leg.lo), std::fabs(leg.hi));
  std::vector<std::string> swatch_labels;
  float swatch_w = 0;
  for (auto const& s : leg.swatches) {
    swatch_labels.push_back(format_value(s.value));
    swatch_w = std::max(swatch_w, font.width(swatch_labels.back(), px));
  }
  int const sw = int(px);  // swatch side
  int const right = img.width - margin;
  int const x1 = leg.swatches.empty() ? right : right - int(std::ceil(swatch_w)) - sw - 2 * gap;
  int const x0 = x1 - bar_w;
  auto y_of = [&](double v) {
    double const t = leg.hi > leg.lo ? std::clamp((v - leg.lo) / (leg.hi - leg.lo), 0.0, 1.0) : 0.5;
    return float(y1 - 1) - float(t) * float(bar_h - 1);
  };

  // The bar: the colour ramp, or for isosurfaces a neutral field with a
  // band in each surface's colour at its value.
  if (!leg.ramp.empty()) {
    for (int y = y0; y < y1; ++y) {
      float const t = bar_h > 1 ? float(y1 - 1 - y) / float(bar_h - 1) : 0.f;
      float const f = t * float(leg.ramp.size() - 1);
      size_t const i = std::min(size_t(f), leg.ramp.size() - 1), j = std::min(i + 1, leg.ramp.size() - 1);
      glm::vec3 const c = leg.ramp[i] + (f - float(i)) * (leg.ramp[j] - leg.ramp[i]);
      fill_rect(img, x0, y, x1, y + 1, c);
    }
  } else {
    fill_rect(img, x0, y0, x1, y1, ink.halo, 0.6f);
    int const band = std::max(2, int(px / 5));
    for (auto const& s : leg.swatches) {
      int const yc = int(std::lround(y_of(s.value)));
      fill_rect(img, x0, yc - band / 2, x1, yc - band / 2 + band, s.colour);
    }
  }
  frame_rect(img, x0 - 1, y0 - 1, x1 + 1, y1 + 1, ink.text);

  // Ticks and their labels at the left.
  float const mid = 0.36f * px;  // half a digit's height: labels centred on their tick
  for (double v : ticks) {
    int const y = int(std::lround(y_of(v)));
    fill_rect(img, x0 - 1 - tick, y, x0 - 1, y + 1, ink.text);
    draw_text(img, font, format_tick(v, step, magnitude), float(x0 - 1 - tick - gap), float(y) + mid, px,
              Align::right, ink);
  }

  // Isosurface swatches at the right, in value order, pushed apart so that
  // labels never overlap, kept beside the bar.
  if (!leg.swatches.empty()) {
    std::vector<size_t> order(leg.swatches.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return leg.swatches[a].value > leg.swatches[b].value; });
    float const line = 1.2f * px;
    std::vector<float> yc(order.size());
    for (size_t k = 0; k < order.size(); ++k) {
      yc[k] = y_of(leg.swatches[order[k]].value);
      if (k > 0) yc[k] = std::max(yc[k], yc[k - 1] + line);
    }
    float const overflow = yc.back() - float(y1 - 1) - 0.5f * line;
    if (overflow > 0)
      for (size_t k = order.size(); k-- > 0;) {
        float const limit = k + 1 < order.size() ? yc[k + 1] - line : float(y1 - 1);
        yc[k] = std::min(yc[k], limit);
      }
    for (size_t k = 0; k < order.size(); ++k) {
      auto const& s = leg.swatches[order[k]];
      int const sy = int(std::lround(yc[k])) - sw / 2, sx = x1 + 1 + gap;
      fill_rect(img, sx, sy, sx + sw, sy + sw, s.colour);
      frame_rect(img, sx - 1, sy - 1, sx + sw + 1, sy + sw + 1, ink.text);
      draw_text(img, font, swatch_labels[order[k]], float(sx + sw + gap), yc[k] + mid, px, Align::left, ink);
    }
  }

  // The array's name above the bar, right-aligned, cut to the image.
  std::string const name = font.fit(leg.name, px, float(img.width - 2 * margin));
  draw_text(img, font, name, float(right), float(y0) - px * 0.7f, px, Align::right, ink);
}

/// Draws `title` centred at the top of `img`, 1.5 times the legend's text
/// size, cut to the image's width.
inline void draw_title(cellray::Image& img, Font const& font, std::string const& title, glm::vec4 background) {
  float const px = 1.5f * legend_font_px(img.width, img.height);
  float const margin = legend_font_px(img.width, img.height);
  std::string const t = font.fit(title, px, float(img.width) - 2.f * margin);
  draw_text(img, font, t, 0.5f * float(img.width), margin + font.ascent(px), px, Align::centre, Ink(background));
}

}  // namespace cellray_render
