// Calibration targets: the board model, its printable image, and corner detection.
//
// Board frame (both board types; millimetres): origin at the first inner corner (the top-left
// inner corner of the board as printed), x along the first row of `cols` inner corners (to the
// right on the print), y down the `rows` rows (downward on the print), z = x cross y, pointing
// into the print (away from a viewer who sees its face). All corners have z = 0.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "base/error.h"

namespace revolve::calibrate {

enum class BoardType {
  kChessboard,  // black and white squares; the whole board must be in view
  kCharuco,     // chessboard with ArUco markers in the white squares; partial views work
};

// "chessboard" / "charuco".
std::string_view ToString(BoardType type);

// True when this build can detect ChArUco boards (OpenCV's aruco module was found).
bool CharucoSupported();

// A printed calibration target. Both types count INNER corners: `cols` x `rows` corners where
// four squares meet, i.e. (cols + 1) x (rows + 1) squares. The square at the printed top-left is
// black (a ChArUco board's top-left square is black too, its white squares hold the markers).
struct Board {
  BoardType type = BoardType::kChessboard;
  int cols = 9;
  int rows = 6;
  double square_mm = 20.0;
  double marker_mm = 15.0;                  // ChArUco: side of a marker, < square_mm
  std::string dictionary = "DICT_5X5_100";  // ChArUco: OpenCV predefined dictionary name

  // bad_input naming the field when the board cannot work: fewer than 3 corners a side,
  // square_mm <= 0, ChArUco marker not smaller than its square, an unknown dictionary or too few
  // markers in it, or ChArUco in a build without the aruco module (unsupported).
  Expected<void> Validate() const;
  // True when every view identifies each corner the same way: ChArUco boards, and chessboards
  // with cols + rows odd (e.g. 9x6). A 7x5 or 8x6 chessboard looks the same turned by 180 deg:
  // fine for the lens, refused for the axis (whose fit compares the board across stops).
  bool OrientationUnique() const;

  int CornerCount() const { return cols * rows; }
  // The inner corner with index `id` (row-major: id = row * cols + col), board frame.
  Eigen::Vector3d Corner(int id) const;
  // Size of the squared area, (cols + 1) x (rows + 1) squares.
  double WidthMm() const { return (cols + 1) * square_mm; }
  double HeightMm() const { return (rows + 1) * square_mm; }
  // "chessboard 9x6 inner corners, 20 mm squares".
  std::string Describe() const;
};

// An image of the board drawn on white paper, and where the board frame lies on it.
struct BoardImage {
  cv::Mat image;  // CV_8UC1: 255 paper, 0 ink
  // Homogeneous image pixel (x, y, 1) -> board-frame point (X_mm, Y_mm, 1). Pixel (0, 0) is the
  // centre of the top-left pixel.
  Eigen::Matrix3d board_from_image = Eigen::Matrix3d::Identity();
  double px_per_mm = 0.0;
};

// Draws `board` at `px_per_mm` with a white margin of `margin_mm` around the squares. With
// `antialias`, each pixel holds the ink's area coverage (grey along edges: a texture for
// rendering); without, pure black and white (for printing). Errors as Board::Validate.
Expected<BoardImage> DrawBoard(const Board& board, double px_per_mm, double margin_mm,
                               bool antialias = false);

// The board to print: 300 dpi, a 10 mm white margin. Printed at 100 % scale it measures
// (WidthMm() + 20) x (HeightMm() + 20) mm; measure one square with a ruler and configure
// square_mm with what you measured.
Expected<BoardImage> PrintableBoard(const Board& board);

// The corners of one board found in one image.
struct Detection {
  std::vector<cv::Point2f> image_px;  // detected corners (distorted pixels, as in the image)
  std::vector<int> ids;               // corner ids (Board::Corner), same order
  std::vector<cv::Point3f> board_mm;  // the same corners in the board frame
  std::size_t size() const { return image_px.size(); }
};

struct DetectOptions {
  // ChArUco: fewer corners than this is no detection (a chessboard is always complete).
  int min_charuco_corners = 8;
  // Chessboard: identify the board size seen when the configured one is not found, so that the
  // error can say "found 7x5, configured 9x6" (costs one more search on failure).
  bool diagnose_failures = true;
};

// Finds the board in `image` (CV_8UC1 or CV_8UC3 BGR) with sub-pixel corners. The corner order
// is canonical (same physical corner -> same id in every view; for chessboards only when
// Board::OrientationUnique): chessboard corners are reordered so that the board frame is
// right-handed as seen and the printed top-left square is black.
// Errors (bad_input): no board found, with the likely cause ("no chessboard of 9x6 inner corners
// found, but one of 7x5: the printed board does not match [calibration.board] cols/rows ..." when
// options.diagnose_failures, else "... is the whole board in view, evenly lit, sharp ...?");
// ChArUco markers that do not belong to the configured board; too few ChArUco corners.
Expected<Detection> DetectBoard(const cv::Mat& image, const Board& board,
                                const DetectOptions& options = {});

}  // namespace revolve::calibrate
