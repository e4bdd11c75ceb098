#include "calibrate/board.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

#include <fmt/format.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#if REVOLVE_HAVE_ARUCO
#include <opencv2/aruco.hpp>
#include <opencv2/aruco/charuco.hpp>
#endif

namespace revolve::calibrate {
namespace {

struct DictionaryName {
  std::string_view name;
  int id;     // cv::aruco::PREDEFINED_DICTIONARY_NAME
  int count;  // markers in it
};

// cv::aruco::PREDEFINED_DICTIONARY_NAME values (stable across OpenCV 4.x).
constexpr std::array<DictionaryName, 17> kDictionaries = {{
    {"DICT_4X4_50", 0, 50},
    {"DICT_4X4_100", 1, 100},
    {"DICT_4X4_250", 2, 250},
    {"DICT_4X4_1000", 3, 1000},
    {"DICT_5X5_50", 4, 50},
    {"DICT_5X5_100", 5, 100},
    {"DICT_5X5_250", 6, 250},
    {"DICT_5X5_1000", 7, 1000},
    {"DICT_6X6_50", 8, 50},
    {"DICT_6X6_100", 9, 100},
    {"DICT_6X6_250", 10, 250},
    {"DICT_6X6_1000", 11, 1000},
    {"DICT_7X7_50", 12, 50},
    {"DICT_7X7_100", 13, 100},
    {"DICT_7X7_250", 14, 250},
    {"DICT_7X7_1000", 15, 1000},
    {"DICT_ARUCO_ORIGINAL", 16, 1024},
}};

const DictionaryName* FindDictionary(std::string_view name) {
  for (const DictionaryName& d : kDictionaries) {
    if (d.name == name) return &d;
  }
  return nullptr;
}

int MarkerCount(const Board& board) { return (board.cols + 1) * (board.rows + 1) / 2; }

cv::Mat ToGrey(const cv::Mat& image) {
  if (image.channels() == 1) return image;
  cv::Mat grey;
  cv::cvtColor(image, grey, image.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
  return grey;
}

// Mean grey level in a 3x3 patch around a sub-pixel point.
double SampleGrey(const cv::Mat& grey, const cv::Point2f& at) {
  cv::Mat patch;
  cv::getRectSubPix(grey, cv::Size(3, 3), at, patch, CV_32F);
  return cv::mean(patch)[0];
}

// Puts chessboard corners in the canonical order of board.h: the board frame right-handed as
// seen (x cross y along +z of the image's u cross v), then the printed top-left square black.
// OpenCV returns any of the four traversals of the grid that keep rows of `cols` corners. With
// cols + rows even the last step cannot tell the two remaining traversals apart (the score is
// ~0 either way) and the order stays as found.
void CanonicaliseChessboard(const cv::Mat& grey, int cols, int rows,
                            std::vector<cv::Point2f>* corners) {
  std::vector<cv::Point2f>& p = *corners;
  const cv::Point2f dx = p[1] - p[0];
  const cv::Point2f dy = p[cols] - p[0];
  if (dx.x * dy.y - dx.y * dy.x < 0.0f) {  // mirrored traversal: reverse each row
    for (int r = 0; r < rows; ++r) {
      const std::ptrdiff_t row_start = static_cast<std::ptrdiff_t>(r) * cols;
      std::reverse(p.begin() + row_start, p.begin() + row_start + cols);
    }
  }
  // Inner square between corners (c, r), (c+1, r), (c, r+1), (c+1, r+1) is square (c+1, r+1),
  // black when c + r is even. A 180-degree turn of the traversal flips that parity (cols + rows
  // is odd), so the sign of this score tells the two apart using every inner square.
  double score = 0.0;
  for (int r = 0; r + 1 < rows; ++r) {
    for (int c = 0; c + 1 < cols; ++c) {
      const cv::Point2f centre = 0.25f * (p[r * cols + c] + p[r * cols + c + 1] +
                                          p[(r + 1) * cols + c] + p[(r + 1) * cols + c + 1]);
      const double grey_level = SampleGrey(grey, centre);
      score += ((c + r) % 2 == 0) ? -grey_level : grey_level;
    }
  }
  if (score < 0.0) std::reverse(p.begin(), p.end());  // the "black" squares were the light ones
}

Detection MakeDetection(const Board& board, std::vector<cv::Point2f> image_px,
                        std::vector<int> ids) {
  Detection d;
  d.image_px = std::move(image_px);
  d.ids = std::move(ids);
  d.board_mm.reserve(d.ids.size());
  for (int id : d.ids) {
    const Eigen::Vector3d c = board.Corner(id);
    d.board_mm.emplace_back(static_cast<float>(c.x()), static_cast<float>(c.y()), 0.0f);
  }
  return d;
}

// Sub-pixel refinement with a window of `fraction` of the smallest corner spacing (large enough
// to average noise, small enough to stay clear of neighbouring corners and markers).
void RefineCorners(const cv::Mat& grey, double fraction, std::vector<cv::Point2f>* corners) {
  const std::vector<cv::Point2f>& p = *corners;
  double spacing = 1e9;
  for (std::size_t a = 0; a < p.size(); ++a) {
    for (std::size_t b = a + 1; b < p.size(); ++b)
      spacing = std::min(spacing, cv::norm(p[a] - p[b]));
  }
  if (p.size() < 2) return;
  const int half = std::clamp(static_cast<int>(fraction * spacing), 2, 15);
  cv::cornerSubPix(grey, *corners, cv::Size(half, half), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-4));
}

Expected<Detection> DetectChessboard(const cv::Mat& grey, const Board& board,
                                     const DetectOptions& options) {
  const cv::Size pattern(board.cols, board.rows);
  std::vector<cv::Point2f> corners;
  // The classic detector is fast and, refined, the most accurate; the sector-based one finds
  // boards the classic one misses (blur, uneven light). (The classic one's NORMALIZE_IMAGE can
  // take tens of seconds on an image holding a board of another size: not used.)
  bool found = cv::findChessboardCorners(grey, pattern, corners,
                                         cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_FAST_CHECK);
  if (!found) {
    found = cv::findChessboardCornersSB(grey, pattern, corners, cv::CALIB_CB_NORMALIZE_IMAGE);
  }
  if (!found || corners.size() != static_cast<std::size_t>(board.CornerCount())) {
    if (options.diagnose_failures) {
      std::vector<cv::Point2f> any;
      cv::Mat meta;
      if (cv::findChessboardCornersSB(grey, cv::Size(3, 3), any,
                                      cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_LARGER, meta) &&
          !meta.empty() && (meta.cols != board.cols || meta.rows != board.rows) &&
          (meta.cols != board.rows || meta.rows != board.cols)) {
        // meta holds the grid found; its orientation is arbitrary: say the larger count first
        // when the configuration does.
        int found_cols = meta.cols;
        int found_rows = meta.rows;
        if ((found_cols < found_rows) != (board.cols < board.rows))
          std::swap(found_cols, found_rows);
        return MakeError(
            ErrorCode::kBadInput,
            fmt::format("no chessboard of {}x{} inner corners found, but one of {}x{}: the printed "
                        "board does not match [calibration.board] cols/rows (count the inner "
                        "corners, where four squares meet), or part of the board is out of view",
                        board.cols, board.rows, found_cols, found_rows));
      }
    }
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("no chessboard of {}x{} inner corners found: is the whole board "
                                 "in view, evenly lit, sharp and large enough in the image?",
                                 board.cols, board.rows));
  }
  RefineCorners(grey, 0.4, &corners);
  CanonicaliseChessboard(grey, board.cols, board.rows, &corners);
  std::vector<int> ids(corners.size());
  for (std::size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<int>(i);
  return MakeDetection(board, std::move(corners), std::move(ids));
}

#if REVOLVE_HAVE_ARUCO
cv::Ptr<cv::aruco::CharucoBoard> MakeCharuco(const Board& board) {
  const DictionaryName* name = FindDictionary(board.dictionary);
  cv::Ptr<cv::aruco::Dictionary> dictionary = cv::aruco::getPredefinedDictionary(name->id);
  return cv::aruco::CharucoBoard::create(board.cols + 1, board.rows + 1,
                                         static_cast<float>(board.square_mm),
                                         static_cast<float>(board.marker_mm), dictionary);
}

Expected<Detection> DetectCharuco(const cv::Mat& grey, const Board& board,
                                  const DetectOptions& options) {
  cv::Ptr<cv::aruco::CharucoBoard> charuco = MakeCharuco(board);
  std::vector<std::vector<cv::Point2f>> marker_corners;
  std::vector<int> marker_ids;
  cv::Ptr<cv::aruco::DetectorParameters> parameters = cv::aruco::DetectorParameters::create();
  cv::aruco::detectMarkers(grey, charuco->dictionary, marker_corners, marker_ids, parameters);
  if (marker_ids.empty()) {
    return MakeError(
        ErrorCode::kBadInput,
        fmt::format("no {} markers found: is the ChArUco board in view, evenly lit "
                    "and sharp, and is [calibration.board] dictionary the printed one?",
                    board.dictionary));
  }
  const int markers = static_cast<int>(charuco->ids.size());
  const int max_id = *std::max_element(marker_ids.begin(), marker_ids.end());
  if (max_id >= markers) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("found marker id {}, but a ChArUco board of {}x{} inner corners "
                                 "has markers 0..{}: the printed board is larger than "
                                 "[calibration.board] cols/rows say",
                                 max_id, board.cols, board.rows, markers - 1));
  }
  std::vector<cv::Point2f> corners;
  std::vector<int> ids;
  cv::aruco::interpolateCornersCharuco(marker_corners, marker_ids, grey, charuco, corners, ids);
  if (static_cast<int>(ids.size()) < options.min_charuco_corners) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("only {} ChArUco corners found (need {}): bring more of the board "
                                 "into view",
                                 ids.size(), options.min_charuco_corners));
  }
  // interpolateCornersCharuco's own refinement leaves a bias of about half a pixel (OpenCV 4.6,
  // seen on rendered boards): refine again, the window clear of the markers (inset by half the
  // difference between square and marker).
  RefineCorners(grey, 0.8 * 0.5 * (board.square_mm - board.marker_mm) / board.square_mm, &corners);
  // OpenCV 4.6's ChArUco corner i is our corner i (row-major from the top-left inner corner; its
  // frame has our axes, with the origin one square up and left): see the board-frame test.
  return MakeDetection(board, std::move(corners), std::move(ids));
}
#endif

}  // namespace

std::string_view ToString(BoardType type) {
  return type == BoardType::kCharuco ? "charuco" : "chessboard";
}

bool CharucoSupported() { return REVOLVE_HAVE_ARUCO != 0; }

Expected<void> Board::Validate() const {
  if (cols < 3 || rows < 3) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("board cols/rows: {}x{} inner corners is too small (at least 3x3)",
                                 cols, rows));
  }
  if (cols > 100 || rows > 100) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("board cols/rows: {}x{} inner corners is too large", cols, rows));
  }
  if (!(square_mm > 0.0) || !std::isfinite(square_mm)) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("board square_mm: {} must be a positive length", square_mm));
  }
  if (type == BoardType::kChessboard) return {};
  if (!CharucoSupported()) {
    return MakeError(ErrorCode::kUnsupported,
                     "board type \"charuco\": this build has no OpenCV aruco module (install "
                     "libopencv-contrib-dev and rebuild), use type = \"chessboard\"");
  }
  if (!(marker_mm > 0.0) || marker_mm >= square_mm) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("board marker_mm: {} must be positive and smaller than square_mm "
                                 "({})",
                                 marker_mm, square_mm));
  }
  const DictionaryName* d = FindDictionary(dictionary);
  if (d == nullptr) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("board dictionary: \"{}\" is not an OpenCV predefined dictionary "
                                 "(e.g. DICT_5X5_100, DICT_6X6_250)",
                                 dictionary));
  }
  if (d->count < MarkerCount(*this)) {
    return MakeError(ErrorCode::kBadInput,
                     fmt::format("board dictionary: {} holds {} markers, a ChArUco board of {}x{} "
                                 "inner corners needs {}",
                                 dictionary, d->count, cols, rows, MarkerCount(*this)));
  }
  return {};
}

bool Board::OrientationUnique() const {
  return type == BoardType::kCharuco || (cols + rows) % 2 == 1;
}

Eigen::Vector3d Board::Corner(int id) const {
  const int column = id % cols;
  const int row = id / cols;  // whole rows
  return Eigen::Vector3d(column * square_mm, row * square_mm, 0.0);
}

std::string Board::Describe() const {
  std::string s =
      fmt::format("{} {}x{} inner corners, {} mm squares", ToString(type), cols, rows, square_mm);
  if (type == BoardType::kCharuco) s += fmt::format(", {} mm {} markers", marker_mm, dictionary);
  return s;
}

Expected<BoardImage> DrawBoard(const Board& board, double px_per_mm, double margin_mm,
                               bool antialias) {
  if (auto valid = board.Validate(); !valid) return std::unexpected(valid.error());
  if (!(px_per_mm > 0.0) || !(margin_mm >= 0.0)) {
    return MakeError(ErrorCode::kBadInput, "DrawBoard: px_per_mm must be > 0, margin_mm >= 0");
  }
  const int pattern_w = static_cast<int>(std::lround(board.WidthMm() * px_per_mm));
  const int pattern_h = static_cast<int>(std::lround(board.HeightMm() * px_per_mm));
  const int margin_px = static_cast<int>(std::lround(margin_mm * px_per_mm));
  if (static_cast<double>(pattern_w) * pattern_h > 2.0e8) {
    return MakeError(ErrorCode::kBadInput, "DrawBoard: image too large (lower px_per_mm)");
  }
  // Exact scales of the pattern after rounding to whole pixels.
  const double sx = pattern_w / board.WidthMm();
  const double sy = pattern_h / board.HeightMm();
  cv::Mat pattern;
  if (board.type == BoardType::kChessboard) {
    // Square (i, j) (i = 0..cols, j = 0..rows from the top-left) is black when i + j is even.
    // Per axis: the fractions of a pixel's extent over even and over odd squares; the ink
    // coverage of a pixel is then even_x * even_y + odd_x * odd_y (exact for box pixels).
    const auto fractions = [&](int n_pixels, double scale, int squares) {
      std::vector<std::pair<double, double>> f(static_cast<std::size_t>(n_pixels));
      const double s = board.square_mm;
      for (int p = 0; p < n_pixels; ++p) {
        const double a = p / scale;
        const double b = (p + 1) / scale;
        if (!antialias) {
          const int i = std::min(squares - 1, static_cast<int>(0.5 * (a + b) / s));
          f[static_cast<std::size_t>(p)] = i % 2 == 0 ? std::pair(1.0, 0.0) : std::pair(0.0, 1.0);
          continue;
        }
        double even = 0.0;
        double odd = 0.0;
        for (int i = std::max(0, static_cast<int>(a / s) - 1);
             i <= std::min(squares - 1, static_cast<int>(b / s) + 1); ++i) {
          const double overlap = std::min(b, (i + 1) * s) - std::max(a, i * s);
          if (overlap > 0.0) (i % 2 == 0 ? even : odd) += overlap;
        }
        f[static_cast<std::size_t>(p)] = {even / (b - a), odd / (b - a)};
      }
      return f;
    };
    const auto fx = fractions(pattern_w, sx, board.cols + 1);
    const auto fy = fractions(pattern_h, sy, board.rows + 1);
    pattern.create(pattern_h, pattern_w, CV_8UC1);
    for (int y = 0; y < pattern_h; ++y) {
      auto* row = pattern.ptr<std::uint8_t>(y);
      const auto [even_y, odd_y] = fy[static_cast<std::size_t>(y)];
      for (int x = 0; x < pattern_w; ++x) {
        const auto [even_x, odd_x] = fx[static_cast<std::size_t>(x)];
        const double ink = even_x * even_y + odd_x * odd_y;
        row[x] = cv::saturate_cast<std::uint8_t>(255.0 * (1.0 - ink));
      }
    }
  } else {
#if REVOLVE_HAVE_ARUCO
    // OpenCV draws whole pixels; for a texture, draw 4x larger and average.
    const int k = antialias ? 4 : 1;
    MakeCharuco(board)->draw(cv::Size(k * pattern_w, k * pattern_h), pattern, 0, 1);
    if (k > 1) cv::resize(pattern, pattern, cv::Size(pattern_w, pattern_h), 0, 0, cv::INTER_AREA);
#endif
  }
  BoardImage out;
  cv::copyMakeBorder(pattern, out.image, margin_px, margin_px, margin_px, margin_px,
                     cv::BORDER_CONSTANT, cv::Scalar(255));
  out.px_per_mm = px_per_mm;
  // Pixel centre x lies (x - margin_px + 0.5) / sx mm right of the pattern's left edge, which is
  // one square left of the board origin.
  out.board_from_image << 1.0 / sx, 0.0, (0.5 - margin_px) / sx - board.square_mm,  //
      0.0, 1.0 / sy, (0.5 - margin_px) / sy - board.square_mm,                      //
      0.0, 0.0, 1.0;
  return out;
}

Expected<BoardImage> PrintableBoard(const Board& board) {
  return DrawBoard(board, 300.0 / 25.4, 10.0);
}

Expected<Detection> DetectBoard(const cv::Mat& image, const Board& board,
                                const DetectOptions& options) {
  if (auto valid = board.Validate(); !valid) return std::unexpected(valid.error());
  if (image.empty() || image.depth() != CV_8U) {
    return MakeError(ErrorCode::kBadInput, "DetectBoard: expected a non-empty 8-bit image");
  }
  const cv::Mat grey = ToGrey(image);
  if (board.type == BoardType::kChessboard) return DetectChessboard(grey, board, options);
#if REVOLVE_HAVE_ARUCO
  return DetectCharuco(grey, board, options);
#else
  return MakeError(ErrorCode::kUnsupported, "ChArUco boards need OpenCV's aruco module");
#endif
}

}  // namespace revolve::calibrate
