#include "libwheelchair/visualization/Plot.h"

#include <mrpt/img/CImage.h>
#include <opencv2/imgcodecs.hpp>

#include "libwheelchair/util/AtomicFile.h"
#include "libwheelchair/util/Text.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <stdexcept>

namespace wheelchair::visualization {
namespace {

constexpr double kPi = 3.14159265358979323846;
using Pts = std::vector<std::pair<double, double>>;

// Glyph bitmap of a text line in MRPT's 10x20 font (one byte per pixel, 0..255).
struct Glyphs {
  int w = 0, h = 0;
  std::vector<uint8_t> a;
};

Glyphs renderGlyphs(const std::string& s) {
  Glyphs g;
  g.w = std::max<int>(1, 10 * static_cast<int>(s.size()));
  g.h = 20;
  mrpt::img::CImage im(g.w, g.h, mrpt::img::CH_RGB);
  im.filledRectangle(0, 0, g.w - 1, g.h - 1, mrpt::img::TColor(0, 0, 0));
  im.selectTextFont("10x20");
  im.textOut(0, 0, s, mrpt::img::TColor(255, 255, 255));
  g.a.resize(static_cast<std::size_t>(g.w) * g.h);
  for (int y = 0; y < g.h; ++y) {
    const uint8_t* row = im.ptrLine<uint8_t>(y);
    for (int x = 0; x < g.w; ++x) g.a[static_cast<std::size_t>(y) * g.w + x] = row[3 * x + 1];
  }
  return g;
}

double sampleGlyph(const Glyphs& g, double u, double v) {
  // Bilinear sample at glyph coordinates (pixel centres at +0.5).
  u -= 0.5;
  v -= 0.5;
  const int x0 = static_cast<int>(std::floor(u)), y0 = static_cast<int>(std::floor(v));
  const double fx = u - x0, fy = v - y0;
  auto at = [&](int x, int y) -> double {
    if (x < 0 || y < 0 || x >= g.w || y >= g.h) return 0.0;
    return g.a[static_cast<std::size_t>(y) * g.w + x] / 255.0;
  };
  return (1 - fx) * (1 - fy) * at(x0, y0) + fx * (1 - fy) * at(x0 + 1, y0) +
         (1 - fx) * fy * at(x0, y0 + 1) + fx * fy * at(x0 + 1, y0 + 1);
}

Pts circlePts(double x, double y, double r, int n) {
  Pts p;
  p.reserve(n);
  for (int i = 0; i < n; ++i) {
    const double a = 2 * kPi * i / n;
    p.emplace_back(x + r * std::cos(a), y + r * std::sin(a));
  }
  return p;
}

std::string tickLabel(double v, double step) {
  const int dec = std::max(0, static_cast<int>(-std::floor(std::log10(step) + 1e-9)));
  if (std::fabs(v) < step * 1e-6) v = 0.0;
  return fmt::format("{:.{}f}", v, dec);
}

}  // namespace

// ----------------------------------------------------------------------------------- Raster

Raster::Raster(int width, int height, int supersample, Color bg)
    : w_(width), h_(height), s_(std::max(1, supersample)) {
  if (width <= 0 || height <= 0) throw std::invalid_argument("Raster: empty size");
  px_.resize(static_cast<std::size_t>(w_ * s_) * (h_ * s_) * 3);
  for (std::size_t i = 0; i < px_.size(); i += 3) {
    px_[i] = bg.r;
    px_[i + 1] = bg.g;
    px_[i + 2] = bg.b;
  }
  clearClip();
}

void Raster::setClip(double x0, double y0, double x1, double y1) {
  cx0_ = std::max(0, static_cast<int>(std::floor(x0 * s_)));
  cy0_ = std::max(0, static_cast<int>(std::floor(y0 * s_)));
  cx1_ = std::min(w_ * s_, static_cast<int>(std::ceil(x1 * s_)));
  cy1_ = std::min(h_ * s_, static_cast<int>(std::ceil(y1 * s_)));
}

void Raster::clearClip() {
  cx0_ = cy0_ = 0;
  cx1_ = w_ * s_;
  cy1_ = h_ * s_;
}

void Raster::blend(int X, int Y, Color c, double a) {
  if (X < cx0_ || Y < cy0_ || X >= cx1_ || Y >= cy1_ || a <= 0) return;
  uint8_t* p = &px_[(static_cast<std::size_t>(Y) * (w_ * s_) + X) * 3];
  if (a >= 1) {
    p[0] = c.r;
    p[1] = c.g;
    p[2] = c.b;
    return;
  }
  p[0] = static_cast<uint8_t>(std::lround(p[0] + a * (c.r - p[0])));
  p[1] = static_cast<uint8_t>(std::lround(p[1] + a * (c.g - p[1])));
  p[2] = static_cast<uint8_t>(std::lround(p[2] + a * (c.b - p[2])));
}

void Raster::fillPolygon(const Pts& pts_in, Color c, double alpha) {
  if (pts_in.size() < 3) return;
  Pts pts;
  pts.reserve(pts_in.size());
  double ymin = std::numeric_limits<double>::infinity(), ymax = -ymin;
  for (const auto& [x, y] : pts_in) {
    if (!std::isfinite(x) || !std::isfinite(y)) return;
    pts.emplace_back(x * s_, y * s_);
    ymin = std::min(ymin, y * s_);
    ymax = std::max(ymax, y * s_);
  }
  const int Y0 = std::max(cy0_, static_cast<int>(std::floor(ymin)));
  const int Y1 = std::min(cy1_ - 1, static_cast<int>(std::ceil(ymax)));
  std::vector<double> xs;
  for (int Y = Y0; Y <= Y1; ++Y) {
    const double yc = Y + 0.5;
    xs.clear();
    for (std::size_t i = 0, j = pts.size() - 1; i < pts.size(); j = i++) {
      const auto& [xi, yi] = pts[i];
      const auto& [xj, yj] = pts[j];
      if ((yi <= yc && yj > yc) || (yj <= yc && yi > yc))
        xs.push_back(xi + (yc - yi) / (yj - yi) * (xj - xi));
    }
    std::sort(xs.begin(), xs.end());
    for (std::size_t k = 0; k + 1 < xs.size(); k += 2) {
      const int X0 = std::max(cx0_, static_cast<int>(std::ceil(xs[k] - 0.5)));
      const int X1 = std::min(cx1_ - 1, static_cast<int>(std::floor(xs[k + 1] - 0.5)));
      for (int X = X0; X <= X1; ++X) blend(X, Y, c, alpha);
    }
  }
}

void Raster::disc(double x, double y, double r, Color c, double alpha) {
  fillPolygon(circlePts(x, y, r, std::clamp(static_cast<int>(r * s_ * 2), 8, 48)), c, alpha);
}

void Raster::line(double x0, double y0, double x1, double y1, Color c, double width, double alpha) {
  const double dx = x1 - x0, dy = y1 - y0, L = std::hypot(dx, dy);
  const double hw = std::max(width, 0.5) / 2;
  if (L < 1e-9) {
    disc(x0, y0, hw, c, alpha);
    return;
  }
  const double nx = -dy / L * hw, ny = dx / L * hw;
  fillPolygon({{x0 + nx, y0 + ny}, {x1 + nx, y1 + ny}, {x1 - nx, y1 - ny}, {x0 - nx, y0 - ny}}, c,
              alpha);
  if (width >= 1.5) {
    disc(x0, y0, hw, c, alpha);
    disc(x1, y1, hw, c, alpha);
  }
}

void Raster::polyline(const Pts& pts, Color c, double width, LineStyle style, double alpha) {
  if (style == LineStyle::None || pts.size() < 2) return;
  if (style == LineStyle::Solid) {
    for (std::size_t i = 1; i < pts.size(); ++i) {
      const auto& [x0, y0] = pts[i - 1];
      const auto& [x1, y1] = pts[i];
      if (std::isfinite(x0) && std::isfinite(y0) && std::isfinite(x1) && std::isfinite(y1))
        line(x0, y0, x1, y1, c, width, alpha);
    }
    return;
  }
  // Dash pattern along the arc length.
  const double on = style == LineStyle::Dashed ? 4.0 * width + 4 : 0.01;
  const double off = style == LineStyle::Dashed ? 2.5 * width + 3 : 1.6 * width + 2;
  double phase = 0;  // position within the on+off period
  for (std::size_t i = 1; i < pts.size(); ++i) {
    const auto [x0, y0] = pts[i - 1];
    const auto [x1, y1] = pts[i];
    if (!(std::isfinite(x0) && std::isfinite(y0) && std::isfinite(x1) && std::isfinite(y1)))
      continue;
    const double L = std::hypot(x1 - x0, y1 - y0);
    double s = 0;
    while (s < L) {
      const bool drawing = phase < on;
      const double left = drawing ? on - phase : on + off - phase;
      if (left < 1e-9) {  // at a switch point (rounding): go to the next state
        phase = drawing ? on : 0.0;
        continue;
      }
      const double e = std::min(L, s + left);
      if (!(e > s)) break;  // no progress possible (rounding at the segment's end)
      if (drawing) {
        const double a = s / L, b = e / L;
        if (style == LineStyle::Dotted)
          disc(x0 + a * (x1 - x0), y0 + a * (y1 - y0), width * 0.6, c, alpha);
        else
          line(x0 + a * (x1 - x0), y0 + a * (y1 - y0), x0 + b * (x1 - x0), y0 + b * (y1 - y0), c,
               width, alpha);
      }
      phase = (e == s + left) ? (drawing ? on : 0.0) : phase + (e - s);
      if (phase >= on + off) phase = 0;
      s = e;
    }
  }
}

void Raster::fillRect(double x0, double y0, double x1, double y1, Color c, double alpha) {
  fillPolygon({{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}}, c, alpha);
}

void Raster::rect(double x0, double y0, double x1, double y1, Color c, double width) {
  polyline({{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}, {x0, y0}}, c, width);
}

void Raster::marker(double x, double y, Marker m, double size, Color c) {
  const double h = size / 2;
  switch (m) {
    case Marker::None:
      break;
    case Marker::Square:
      fillRect(x - h, y - h, x + h, y + h, c);
      rect(x - h, y - h, x + h, y + h, colors::black, 1.0);
      break;
    case Marker::Circle:
      disc(x, y, h + 0.8, colors::black);
      disc(x, y, h, c);
      break;
    case Marker::Dot:
      disc(x, y, h, c);
      break;
    case Marker::Cross:
      line(x - h, y - h, x + h, y + h, c, 2.0);
      line(x - h, y + h, x + h, y - h, c, 2.0);
      break;
    case Marker::Triangle: {
      const Pts t{{x, y - h * 1.15}, {x + h, y + h * 0.75}, {x - h, y + h * 0.75}};
      fillPolygon(t, c);
      Pts closed = t;
      closed.push_back(t.front());
      polyline(closed, colors::black, 1.0);
      break;
    }
  }
}

double Raster::textWidth(const std::string& s, double size) {
  return 10.0 * s.size() * size;
}

void Raster::text(double x, double y, const std::string& s, Color c, double size, int halign,
                  int valign, bool vertical) {
  if (s.empty()) return;
  const Glyphs g = renderGlyphs(s);
  const double tw = g.w * size, th = g.h * size;  // output pixels, unrotated
  // Top-left corner of the unrotated text box relative to the anchor.
  const double ox = halign < 0 ? 0 : (halign == 0 ? -tw / 2 : -tw);
  const double oy = valign < 0 ? 0 : (valign == 0 ? -th / 2 : -th);
  // Box in output coordinates.
  double bx0, by0, bx1, by1;
  if (!vertical) {
    bx0 = x + ox;
    by0 = y + oy;
    bx1 = bx0 + tw;
    by1 = by0 + th;
  } else {  // rotated 90 deg CCW about the anchor: text reads bottom to top
    bx0 = x + oy;
    bx1 = bx0 + th;
    by1 = y - ox;
    by0 = by1 - tw;
  }
  const int X0 = static_cast<int>(std::floor(bx0 * s_)), X1 = static_cast<int>(std::ceil(bx1 * s_));
  const int Y0 = static_cast<int>(std::floor(by0 * s_)), Y1 = static_cast<int>(std::ceil(by1 * s_));
  const double k = 1.0 / (size * s_);  // glyph pixels per supersampled pixel
  for (int Y = Y0; Y < Y1; ++Y)
    for (int X = X0; X < X1; ++X) {
      double u, v;
      if (!vertical) {
        u = (X + 0.5 - bx0 * s_) * k;
        v = (Y + 0.5 - by0 * s_) * k;
      } else {
        u = (by1 * s_ - (Y + 0.5)) * k;
        v = (X + 0.5 - bx0 * s_) * k;
      }
      const double a = sampleGlyph(g, u, v);
      if (a > 0.02) blend(X, Y, c, std::min(1.0, a * 1.15));
    }
}

mrpt::img::CImage Raster::toImage() const {
  mrpt::img::CImage im(w_, h_, mrpt::img::CH_RGB);
  const int W = w_ * s_;
  const double n = double(s_) * s_;
  for (int y = 0; y < h_; ++y) {
    uint8_t* row = im.ptrLine<uint8_t>(y);
    for (int x = 0; x < w_; ++x) {
      double acc[3] = {0, 0, 0};
      for (int j = 0; j < s_; ++j)
        for (int i = 0; i < s_; ++i) {
          const uint8_t* p = &px_[(static_cast<std::size_t>(y * s_ + j) * W + x * s_ + i) * 3];
          acc[0] += p[0];
          acc[1] += p[1];
          acc[2] += p[2];
        }
      // CImage keeps OpenCV's BGR order in memory.
      row[3 * x + 0] = static_cast<uint8_t>(std::lround(acc[2] / n));
      row[3 * x + 1] = static_cast<uint8_t>(std::lround(acc[1] / n));
      row[3 * x + 2] = static_cast<uint8_t>(std::lround(acc[0] / n));
    }
  }
  return im;
}

void Raster::save(const std::string& path) const {
  saveImage(toImage(), path);
}

void saveImage(const mrpt::img::CImage& im, const std::string& path) {
  // Encoded in memory (OpenCV picks the format by extension, which the temporary lacks), then
  // written through AtomicFile so a full disk leaves no partial image.
  std::string ext = std::filesystem::path(path).extension().string();
  if (ext.empty()) ext = ".png";
  std::vector<uchar> bytes;
  bool ok = false;
  try {
    ok = cv::imencode(ext, im.asCvMatRef(), bytes);
  } catch (const std::exception& e) {
    throw std::runtime_error(
        fmt::format("{}: cannot encode image: {}", path, util::oneLineMessage(e.what())));
  }
  if (!ok) throw std::runtime_error(fmt::format("{}: cannot encode image as {}", path, ext));
  util::writeFileAtomically(path, [&](std::ostream& os) {
    os.write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
  });
}

// ------------------------------------------------------------------------------------ ticks

std::vector<double> niceTicks(double lo, double hi, int target) {
  std::vector<double> t;
  if (!(hi > lo) || !std::isfinite(lo) || !std::isfinite(hi)) return t;
  const double raw = (hi - lo) / std::max(1, target);
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double norm = raw / mag;
  const double step = (norm < 1.5 ? 1 : norm < 3 ? 2 : norm < 7 ? 5 : 10) * mag;
  for (double v = std::ceil(lo / step - 1e-9) * step; v <= hi + step * 1e-9; v += step)
    t.push_back(std::fabs(v) < step * 1e-9 ? 0.0 : v);
  return t;
}

std::vector<std::pair<double, double>> covarianceEllipse(double cx, double cy, double sxx,
                                                         double sxy, double syy, double k, int n) {
  // Eigen-decomposition of the symmetric 2x2 matrix.
  const double tr = sxx + syy, det = sxx * syy - sxy * sxy;
  const double disc = std::sqrt(std::max(0.0, tr * tr / 4 - det));
  const double l1 = std::max(0.0, tr / 2 + disc), l2 = std::max(0.0, tr / 2 - disc);
  const double ang = 0.5 * std::atan2(2 * sxy, sxx - syy);
  const double a = k * std::sqrt(l1), b = k * std::sqrt(l2);
  Pts p;
  for (int i = 0; i <= n; ++i) {
    const double t = 2 * kPi * i / n;
    const double ex = a * std::cos(t), ey = b * std::sin(t);
    p.emplace_back(cx + ex * std::cos(ang) - ey * std::sin(ang),
                   cy + ex * std::sin(ang) + ey * std::cos(ang));
  }
  return p;
}

// ------------------------------------------------------------------------------------- Plot

namespace {

// The data area of a plot (output pixels) and the axis limits it shows (data units).
struct Frame {
  double x0, y0, x1, y1;
  double xmin, xmax, ymin, ymax;
  double X(double v) const { return x0 + (v - xmin) / (xmax - xmin) * (x1 - x0); }
  double Y(double v) const { return y1 - (v - ymin) / (ymax - ymin) * (y1 - y0); }
};

// Width of the legend box: the longest label plus the line sample.
double legendWidth(const Plot& p) {
  double w = 0;
  for (const auto& b : p.bands)
    if (!b.label.empty()) w = std::max(w, Raster::textWidth(b.label, 0.8));
  for (const auto& s : p.shapes)
    if (!s.label.empty()) w = std::max(w, Raster::textWidth(s.label, 0.8));
  for (const auto& s : p.series)
    if (!s.label.empty()) w = std::max(w, Raster::textWidth(s.label, 0.8));
  return w + 62;
}

// Axis limits: the finite data with a margin, unless given; equal units on both axes if asked.
void axisLimits(const Plot& p, Frame& f) {
  double xmin = std::numeric_limits<double>::infinity(), xmax = -xmin, ymin = xmin, ymax = -xmin;
  auto addX = [&](double v) {
    if (std::isfinite(v)) xmin = std::min(xmin, v), xmax = std::max(xmax, v);
  };
  auto addY = [&](double v) {
    if (std::isfinite(v)) ymin = std::min(ymin, v), ymax = std::max(ymax, v);
  };
  for (const auto& s : p.series)
    for (std::size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i)
      if (std::isfinite(s.x[i]) && std::isfinite(s.y[i])) addX(s.x[i]), addY(s.y[i]);
  for (const auto& b : p.bands)
    for (std::size_t i = 0; i < b.x.size(); ++i) addX(b.x[i]), addY(b.lo[i]), addY(b.hi[i]);
  for (const auto& s : p.shapes)
    for (const auto& [x, y] : s.pts) addX(x), addY(y);
  for (const auto& a : p.annotations) addX(a.x), addY(a.y);
  if (!std::isfinite(xmin)) xmin = 0, xmax = 1;
  if (!std::isfinite(ymin)) ymin = 0, ymax = 1;
  if (xmax - xmin < 1e-9) xmin -= 0.5, xmax += 0.5;
  if (ymax - ymin < 1e-9) ymin -= 0.5, ymax += 0.5;
  const double px = 0.04 * (xmax - xmin), py = 0.06 * (ymax - ymin);
  xmin -= px, xmax += px, ymin -= py, ymax += py;
  if (p.x_range) xmin = p.x_range->first, xmax = p.x_range->second;
  if (p.y_range) ymin = p.y_range->first, ymax = p.y_range->second;
  if (p.equal_aspect) {
    const double ux = (xmax - xmin) / (f.x1 - f.x0), uy = (ymax - ymin) / (f.y1 - f.y0);
    const double u = std::max(ux, uy);
    const double cx = (xmin + xmax) / 2, cy = (ymin + ymax) / 2;
    xmin = cx - u * (f.x1 - f.x0) / 2, xmax = cx + u * (f.x1 - f.x0) / 2;
    ymin = cy - u * (f.y1 - f.y0) / 2, ymax = cy + u * (f.y1 - f.y0) / 2;
  }
  f.xmin = xmin, f.xmax = xmax, f.ymin = ymin, f.ymax = ymax;
}

// Shaded spans, the grid at the ticks and the zero lines (clipped to the data area).
void drawBackground(Raster& r, const Plot& p, const Frame& f, const std::vector<double>& xt,
                    const std::vector<double>& yt) {
  for (const auto& s : p.spans) {
    r.fillRect(f.X(s.x0), f.y0, f.X(s.x1), f.y1, s.color, 0.6);
    if (!s.caption.empty())
      r.text((f.X(s.x0) + f.X(s.x1)) / 2, f.y0 + 4, s.caption, colors::gray, 0.75, 0, -1);
  }
  for (double v : xt) r.line(f.X(v), f.y0, f.X(v), f.y1, Color{215, 215, 215}, 1.0);
  for (double v : yt) r.line(f.x0, f.Y(v), f.x1, f.Y(v), Color{215, 215, 215}, 1.0);
  if (f.xmin < 0 && f.xmax > 0) r.line(f.X(0), f.y0, f.X(0), f.y1, Color{170, 170, 170}, 1.2);
  if (f.ymin < 0 && f.ymax > 0) r.line(f.x0, f.Y(0), f.x1, f.Y(0), Color{170, 170, 170}, 1.2);
}

// Bands, shapes, series (with markers) and annotations, in that order.
// A long line series (more than kDecimateAbove points, no markers) is thinned in output
// pixels before it is drawn (Plot::kDecimateAbove, Plot.h): of each run of consecutive points in
// one supersampled pixel column (1/3 px) only the first, the lowest, the highest and the last
// are kept, in their order, so every column spans the same values. Non-finite points (line
// breaks) are kept and end a run. Shorter series are drawn point for point.
Pts thinnedForDrawing(Pts pts) {
  if (pts.size() <= Plot::kDecimateAbove) return pts;
  Pts out;
  std::size_t a = 0;                 // start of the current run
  auto flush = [&](std::size_t b) {  // the run [a, b)
    if (a >= b) return;
    std::size_t lo = a, hi = a;
    for (std::size_t i = a; i < b; ++i) {
      if (pts[i].second < pts[lo].second) lo = i;
      if (pts[i].second > pts[hi].second) hi = i;
    }
    std::size_t keep[4] = {a, std::min(lo, hi), std::max(lo, hi), b - 1};
    for (int k = 0; k < 4; ++k)
      if (k == 0 || keep[k] != keep[k - 1]) out.push_back(pts[keep[k]]);
  };
  auto column = [](double x) { return std::floor(x * 3.0); };
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const bool finite = std::isfinite(pts[i].first) && std::isfinite(pts[i].second);
    if (!finite) {
      flush(i);
      out.push_back(pts[i]);
      a = i + 1;
    } else if (i > a && column(pts[i].first) != column(pts[a].first)) {
      flush(i);
      a = i;
    }
  }
  flush(pts.size());
  return out;
}

void drawData(Raster& r, const Plot& p, const Frame& f) {
  for (const auto& b : p.bands)
    // Filled per quad (the envelope may self-intersect where lo and hi cross).
    for (std::size_t i = 1; i < b.x.size(); ++i)
      r.fillPolygon({{f.X(b.x[i - 1]), f.Y(b.hi[i - 1])},
                     {f.X(b.x[i]), f.Y(b.hi[i])},
                     {f.X(b.x[i]), f.Y(b.lo[i])},
                     {f.X(b.x[i - 1]), f.Y(b.lo[i - 1])}},
                    b.color, 1.0);
  for (const auto& s : p.shapes) {
    Pts pts;
    for (const auto& [x, y] : s.pts) pts.emplace_back(f.X(x), f.Y(y));
    if (s.fill_alpha > 0) r.fillPolygon(pts, s.color, s.fill_alpha);
    r.polyline(pts, s.color, s.width_px, s.line);
  }
  for (const auto& s : p.series) {
    Pts pts;
    const std::size_t n = std::min(s.x.size(), s.y.size());
    pts.reserve(n);
    for (std::size_t i = 0; i < n; ++i) pts.emplace_back(f.X(s.x[i]), f.Y(s.y[i]));
    if (s.marker == Marker::None) pts = thinnedForDrawing(std::move(pts));
    r.polyline(pts, s.color, s.width_px, s.line);
    if (s.marker != Marker::None)
      for (const auto& [x, y] : pts)
        if (std::isfinite(x) && std::isfinite(y))
          r.marker(x, y, s.marker, s.marker_size_px, s.color);
  }
  for (const auto& a : p.annotations)
    r.text(f.X(a.x) + 6, f.Y(a.y) - 4, a.text, a.color, a.size, -1, 1);
}

// Frame, ticks with their labels, axis labels and the title.
void drawAxes(Raster& r, const Plot& p, const Frame& f, const std::vector<double>& xt,
              const std::vector<double>& yt, int height) {
  r.rect(f.x0, f.y0, f.x1, f.y1, colors::black, 1.4);
  const double xs = xt.size() > 1 ? xt[1] - xt[0] : 1, ys = yt.size() > 1 ? yt[1] - yt[0] : 1;
  for (double v : xt) {
    r.line(f.X(v), f.y1, f.X(v), f.y1 + 6, colors::black, 1.2);
    r.text(f.X(v), f.y1 + 9, tickLabel(v, xs), colors::black, 0.8, 0, -1);
  }
  for (double v : yt) {
    r.line(f.x0 - 6, f.Y(v), f.x0, f.Y(v), colors::black, 1.2);
    r.text(f.x0 - 9, f.Y(v), tickLabel(v, ys), colors::black, 0.8, 1, 0);
  }
  if (!p.xlabel.empty()) r.text((f.x0 + f.x1) / 2, height - 8, p.xlabel, colors::black, 0.9, 0, 1);
  if (!p.ylabel.empty()) r.text(8, (f.y0 + f.y1) / 2, p.ylabel, colors::black, 0.9, 0, -1, true);
  if (!p.title.empty()) r.text((f.x0 + f.x1) / 2, 12, p.title, colors::black, 1.0, 0, -1);
}

// The legend box: series, then shapes, then bands, each with a sample of its line or fill.
void drawLegend(Raster& r, const Plot& p, const Frame& f, double legend_w) {
  struct Entry {
    std::string label;
    int kind;  // 0 series, 1 band, 2 shape
    std::size_t idx;
  };
  std::vector<Entry> es;
  for (std::size_t i = 0; i < p.series.size(); ++i)
    if (!p.series[i].label.empty()) es.push_back({p.series[i].label, 0, i});
  for (std::size_t i = 0; i < p.shapes.size(); ++i)
    if (!p.shapes[i].label.empty()) es.push_back({p.shapes[i].label, 2, i});
  for (std::size_t i = 0; i < p.bands.size(); ++i)
    if (!p.bands[i].label.empty()) es.push_back({p.bands[i].label, 1, i});
  if (es.empty()) return;
  const double lh = 22, lw = legend_w, lhgt = es.size() * lh + 12;
  double lx, ly;
  switch (p.legend) {
    case LegendPosition::TopLeft:
      lx = f.x0 + 10, ly = f.y0 + 10;
      break;
    case LegendPosition::BottomLeft:
      lx = f.x0 + 10, ly = f.y1 - 10 - lhgt;
      break;
    case LegendPosition::BottomRight:
      lx = f.x1 - 10 - lw, ly = f.y1 - 10 - lhgt;
      break;
    case LegendPosition::Outside:
      lx = f.x1 + 16, ly = f.y0;
      break;
    default:
      lx = f.x1 - 10 - lw, ly = f.y0 + 10;
      break;
  }
  r.fillRect(lx, ly, lx + lw, ly + lhgt, colors::white, 0.92);
  r.rect(lx, ly, lx + lw, ly + lhgt, Color{150, 150, 150}, 1.0);
  for (std::size_t k = 0; k < es.size(); ++k) {
    const double cy = ly + 6 + lh * (k + 0.5), sx0 = lx + 8, sx1 = lx + 44;
    const Entry& e = es[k];
    if (e.kind == 0) {
      const Series& s = p.series[e.idx];
      r.polyline({{sx0, cy}, {sx1, cy}}, s.color, s.width_px, s.line);
      if (s.marker != Marker::None)
        r.marker((sx0 + sx1) / 2, cy, s.marker, s.marker_size_px, s.color);
    } else if (e.kind == 1) {
      r.fillRect(sx0, cy - 6, sx1, cy + 6, p.bands[e.idx].color, 1.0);
    } else {
      const Shape& s = p.shapes[e.idx];
      if (s.fill_alpha > 0) r.fillRect(sx0, cy - 6, sx1, cy + 6, s.color, s.fill_alpha);
      r.polyline({{sx0, cy}, {sx1, cy}}, s.color, s.width_px, s.line);
    }
    r.text(sx1 + 8, cy, e.label, colors::black, 0.8, -1, 0);
  }
}

}  // namespace

std::vector<std::size_t> pathPointsToDraw(std::size_t n,
                                          const std::function<double(std::size_t)>& x,
                                          const std::function<double(std::size_t)>& y) {
  std::vector<std::size_t> keep;
  if (n <= Plot::kDecimateAbove) {
    keep.resize(n);
    for (std::size_t i = 0; i < n; ++i) keep[i] = i;
    return keep;
  }
  double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
  for (std::size_t i = 0; i < n; ++i) {
    const double px = x(i), py = y(i);
    if (!std::isfinite(px) || !std::isfinite(py)) continue;
    x0 = std::min(x0, px), x1 = std::max(x1, px), y0 = std::min(y0, py), y1 = std::max(y1, py);
  }
  const double cell = std::max(x1 - x0, y1 - y0) / 4000.0;
  double lx = NAN, ly = NAN;  // the last point kept
  for (std::size_t i = 0; i < n; ++i) {
    const double px = x(i), py = y(i);
    const bool finite = std::isfinite(px) && std::isfinite(py);
    if (finite && i + 1 < n && std::fabs(px - lx) < cell && std::fabs(py - ly) < cell) continue;
    keep.push_back(i);
    lx = px, ly = py;
  }
  return keep;
}

Raster Plot::render(int width, int height) const {
  Raster r(width, height, 3);
  const double title_h = title.empty() ? 14 : 44;
  const double legend_w = legendWidth(*this);
  const bool outside = legend == LegendPosition::Outside;
  Frame f{92, title_h, width - (outside ? legend_w + 30 : 24), height - 66.0, 0, 0, 0, 0};
  axisLimits(*this, f);
  area[0] = f.x0, area[1] = f.y0, area[2] = f.x1, area[3] = f.y1;
  const auto xt = niceTicks(f.xmin, f.xmax, std::max(3, static_cast<int>((f.x1 - f.x0) / 110)));
  const auto yt = niceTicks(f.ymin, f.ymax, std::max(3, static_cast<int>((f.y1 - f.y0) / 70)));
  r.setClip(f.x0, f.y0, f.x1, f.y1);
  drawBackground(r, *this, f, xt, yt);
  drawData(r, *this, f);
  r.clearClip();
  drawAxes(r, *this, f, xt, yt, height);
  drawLegend(r, *this, f, legend_w);
  return r;
}

void Plot::save(const std::string& png_path, int width, int height) const {
  render(width, height).save(png_path);
}

}  // namespace wheelchair::visualization
