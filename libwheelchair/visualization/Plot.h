// Headless 2-D plots written as PNG (no display, no OpenGL): a small supersampled raster
// (anti-aliased lines, filled polygons with alpha) and a Plot of line/marker series with axes,
// "nice" ticks, grid, labels with units, legend and optional equal aspect ratio.
//
// Text uses MRPT's bitmap font (mrpt::img::CCanvas "10x20"), scaled and blended, so nothing
// beyond MRPT is needed; PNG encoding through mrpt::img::CImage::saveToFile.
//
// Example:
//   Plot p;  p.title = "Speed";  p.xlabel = "time (s)";  p.ylabel = "v (m/s)";
//   p.series.push_back({"encoders", t, v, colors::blue});
//   p.save("v.png", 1000, 600);
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace mrpt::img {
class CImage;
}

namespace wheelchair::visualization {

struct Color {
  uint8_t r = 0, g = 0, b = 0;
  bool operator==(const Color& o) const { return r == o.r && g == o.g && b == o.b; }
};

namespace colors {
constexpr Color black{0, 0, 0};
constexpr Color white{255, 255, 255};
constexpr Color red{220, 20, 30};
constexpr Color blue{30, 80, 220};
constexpr Color green{20, 160, 40};
constexpr Color cyan{0, 190, 210};
constexpr Color magenta{200, 40, 200};
constexpr Color orange{240, 140, 0};
constexpr Color gray{128, 128, 128};
constexpr Color light_gray{225, 225, 225};
constexpr Color purple{120, 60, 190};
}  // namespace colors

enum class LineStyle { Solid, Dashed, Dotted, None };
enum class Marker { None, Square, Circle, Cross, Dot, Triangle };

/// A supersampled RGB image: draw in output-pixel coordinates (doubles), downsampled on save.
class Raster {
 public:
  Raster(int width, int height, int supersample = 3, Color background = colors::white);
  int width() const { return w_; }
  int height() const { return h_; }

  void line(double x0, double y0, double x1, double y1, Color c, double width_px,
            double alpha = 1.0);
  void polyline(const std::vector<std::pair<double, double>>& pts, Color c, double width_px,
                LineStyle style = LineStyle::Solid, double alpha = 1.0);
  void fillPolygon(const std::vector<std::pair<double, double>>& pts, Color c, double alpha = 1.0);
  void fillRect(double x0, double y0, double x1, double y1, Color c, double alpha = 1.0);
  void rect(double x0, double y0, double x1, double y1, Color c, double width_px);
  void disc(double x, double y, double radius_px, Color c, double alpha = 1.0);
  void marker(double x, double y, Marker m, double size_px, Color c);
  /// Text with its anchor at (x, y): halign -1 left, 0 centre, 1 right; valign -1 top,
  /// 0 middle, 1 bottom. `size` 1.0 = 20 px high. `vertical` rotates 90 deg counter-clockwise.
  void text(double x, double y, const std::string& s, Color c, double size = 1.0, int halign = -1,
            int valign = -1, bool vertical = false);
  /// Width in output pixels of a text line.
  static double textWidth(const std::string& s, double size = 1.0);

  /// Clip rectangle for subsequent drawing (output pixels); clearClip() removes it.
  void setClip(double x0, double y0, double x1, double y1);
  void clearClip();

  mrpt::img::CImage toImage() const;
  /// Writes a PNG (saveImage); throws std::runtime_error on failure.
  void save(const std::string& path) const;

 private:
  void blend(int X, int Y, Color c, double a);
  int w_, h_, s_;
  std::vector<uint8_t> px_;    // supersampled, RGB
  int cx0_, cy0_, cx1_, cy1_;  // clip, supersampled pixels (inclusive-exclusive)
};

/// Encodes `im` in the format of `path`'s extension (.png, .jpg) and writes it with
/// util::AtomicFile (complete or absent); throws one line naming `path` on any failure.
void saveImage(const mrpt::img::CImage& im, const std::string& path);

struct Series {
  std::string label;  ///< "" = not in the legend
  std::vector<double> x, y;
  Color color = colors::black;
  LineStyle line = LineStyle::Solid;
  double width_px = 2.0;
  Marker marker = Marker::None;
  double marker_size_px = 7.0;
};

/// Filled region between lo(x) and hi(x) (e.g. a +-sigma envelope).
struct Band {
  std::string label;
  std::vector<double> x, lo, hi;
  Color color = colors::red;
  double alpha = 0.2;
};

/// Closed outline (e.g. a covariance ellipse or a footprint), optionally filled.
struct Shape {
  std::string label;
  std::vector<std::pair<double, double>> pts;
  Color color = colors::black;
  double width_px = 2.0;
  LineStyle line = LineStyle::Solid;
  double fill_alpha = 0.0;  ///< 0 = outline only
};

struct Annotation {
  double x = 0, y = 0;
  std::string text;
  Color color = colors::black;
  double size = 0.8;
};

/// Shaded interval of x (e.g. the phases of a drive) with a caption at the top.
struct XSpan {
  double x0 = 0, x1 = 0;
  std::string caption;
  Color color = colors::light_gray;
};

enum class LegendPosition { TopRight, TopLeft, BottomRight, BottomLeft, Outside };

struct Plot {
  std::string title, xlabel, ylabel;
  std::vector<XSpan> spans;
  std::vector<Band> bands;
  std::vector<Shape> shapes;
  std::vector<Series> series;
  std::vector<Annotation> annotations;
  bool equal_aspect = false;
  std::optional<std::pair<double, double>> x_range, y_range;  ///< default: data + 5 %
  LegendPosition legend = LegendPosition::TopRight;
  /// A line series (no markers) of more points than this is thinned before drawing: of each run
  /// of consecutive points in one supersampled pixel column (1/3 px) the first, lowest, highest
  /// and last are drawn, so the figure spans the same values in every column; a one-hour drive's
  /// 560 000 EKF estimates become at most ~4 per column (docs/visualization.md).
  static constexpr std::size_t kDecimateAbove = 20000;

  /// Renders into a new raster of width x height output pixels.
  Raster render(int width, int height) const;
  void save(const std::string& png_path, int width = 1000, int height = 620) const;
  /// The data area of the last render (output pixels): x0, y0, x1, y1.
  mutable double area[4] = {0, 0, 0, 0};
};

/// The points of a path (x-y plot, e.g. a trajectory: point i is (x(i), y(i)), i < n) that are
/// drawn: all of them up to Plot::kDecimateAbove; above, a point closer than 1/4000 of the
/// path's extent (max of its x and y spans) to the last one kept, in x and in y, is skipped (under
/// 1/3 px in a figure up to 1300 px wide); the last point and non-finite points (breaks) are
/// always kept. Returns the indices kept, in order.
std::vector<std::size_t> pathPointsToDraw(std::size_t n,
                                          const std::function<double(std::size_t)>& x,
                                          const std::function<double(std::size_t)>& y);

/// "Nice" tick positions covering [lo, hi] (about `target` of them: steps 1, 2, 5 x 10^k).
std::vector<double> niceTicks(double lo, double hi, int target = 7);

/// Points of the 1-sigma (times `k`) ellipse of a 2x2 covariance [[sxx, sxy], [sxy, syy]]
/// centred at (cx, cy).
std::vector<std::pair<double, double>> covarianceEllipse(double cx, double cy, double sxx,
                                                         double sxy, double syy, double k = 1.0,
                                                         int n = 96);

}  // namespace wheelchair::visualization
