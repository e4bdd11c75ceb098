// Board model, printable image, test renderer and detection: corners land where the rig projects
// them, with the same id for the same physical corner in every view; bad input says why.
#include "calibrate/board.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "calibrate/board_render.h"
#include "sim_rigs.h"

namespace revolve::calibrate {
namespace {

using sim::Rx;
using sim::Rz;

CameraModel IdealLens() {
  CameraModel camera = sim::TrueLens();
  camera.distortion.clear();
  return camera;
}

// The board facing the camera 500 mm away, centred, turned `roll_deg` in its plane.
Eigen::Isometry3d Facing(const Board& board, double roll_deg, double tilt_deg = 0.0) {
  Eigen::Isometry3d cam_from_board = Eigen::Isometry3d::Identity();
  cam_from_board.linear() = Rz(roll_deg) * Rx(tilt_deg);
  const Eigen::Vector3d centre(0.5 * (board.cols - 1) * board.square_mm,
                               0.5 * (board.rows - 1) * board.square_mm, 0.0);
  cam_from_board.translation() =
      Eigen::Vector3d(0.0, 0.0, 500.0) - cam_from_board.linear() * centre;
  return cam_from_board;
}

double MaxCornerError(const Detection& d, const Board& board, const CameraModel& camera,
                      const Eigen::Isometry3d& cam_from_board) {
  double worst = 0.0;
  for (std::size_t i = 0; i < d.size(); ++i) {
    const Eigen::Vector3d h = camera.intrinsics.K() * (cam_from_board * board.Corner(d.ids[i]));
    const Eigen::Vector2d truth = camera.DistortPixel(h.head<2>() / h.z());
    worst = std::max(worst, (truth - Eigen::Vector2d(d.image_px[i].x, d.image_px[i].y)).norm());
    EXPECT_FLOAT_EQ(d.board_mm[i].x, static_cast<float>(board.Corner(d.ids[i]).x()));
    EXPECT_FLOAT_EQ(d.board_mm[i].y, static_cast<float>(board.Corner(d.ids[i]).y()));
  }
  return worst;
}

TEST(Board, ValidateNamesTheProblem) {
  Board board = sim::TestBoard();
  EXPECT_TRUE(board.Validate());
  EXPECT_TRUE(board.OrientationUnique());
  board.cols = 2;
  ASSERT_FALSE(board.Validate());
  EXPECT_NE(board.Validate().error().message.find("too small"), std::string::npos);
  board = sim::TestBoard();
  board.square_mm = 0.0;
  ASSERT_FALSE(board.Validate());
  EXPECT_NE(board.Validate().error().message.find("square_mm"), std::string::npos);
  board = sim::TestBoard();
  board.cols = 7;
  board.rows = 5;
  EXPECT_TRUE(board.Validate());
  EXPECT_FALSE(board.OrientationUnique());
  if (CharucoSupported()) {
    board = sim::TestBoard();
    board.type = BoardType::kCharuco;
    board.marker_mm = 15.0;
    ASSERT_FALSE(board.Validate());
    EXPECT_NE(board.Validate().error().message.find("marker_mm"), std::string::npos);
    board.marker_mm = 11.0;
    board.dictionary = "DICT_9X9_1";
    ASSERT_FALSE(board.Validate());
    EXPECT_NE(board.Validate().error().message.find("dictionary"), std::string::npos);
    board.dictionary = "DICT_4X4_50";
    board.cols = 11;
    board.rows = 8;  // 108 squares, 54 markers > 50
    ASSERT_FALSE(board.Validate());
    EXPECT_NE(board.Validate().error().message.find("needs 54"), std::string::npos);
  }
}

TEST(Board, PrintableBoardSize) {
  const Board board = sim::TestBoard();  // 10 x 7 squares of 15 mm
  Expected<BoardImage> print = PrintableBoard(board);
  ASSERT_TRUE(print) << print.error().ToString();
  const double px_per_mm = 300.0 / 25.4;
  EXPECT_NEAR(print->image.cols, (150.0 + 20.0) * px_per_mm, 2.0);
  EXPECT_NEAR(print->image.rows, (105.0 + 20.0) * px_per_mm, 2.0);
  // The first inner corner: 10 mm margin + one square from the top-left.
  const Eigen::Vector3d origin = print->board_from_image.inverse() * Eigen::Vector3d(0, 0, 1);
  EXPECT_NEAR(origin.x() / origin.z(), 25.0 * px_per_mm - 0.5, 1.0);
  // Top-left square black, paper white.
  EXPECT_EQ(print->image.at<std::uint8_t>(static_cast<int>(15 * px_per_mm),
                                          static_cast<int>(15 * px_per_mm)),
            0);
  EXPECT_EQ(print->image.at<std::uint8_t>(2, 2), 255);
}

// Same physical corner, same id, whichever way the board is turned in the image; corners within
// a small fraction of a pixel of the projection of the board model.
TEST(Board, DetectionIsCanonicalAndAccurate) {
  const Board board = sim::TestBoard();
  const CameraModel camera = sim::TrueLens();
  for (double roll : {0.0, 90.0, 180.0, 270.0, 35.0, -150.0}) {
    SCOPED_TRACE(roll);
    const Eigen::Isometry3d pose = Facing(board, roll, 25.0);
    Expected<cv::Mat> image = RenderBoard(camera, pose, board);
    ASSERT_TRUE(image) << image.error().ToString();
    Expected<Detection> d = DetectBoard(*image, board);
    ASSERT_TRUE(d) << d.error().ToString();
    ASSERT_EQ(d->size(), 54u);
    EXPECT_LT(MaxCornerError(*d, board, camera, pose), 0.25);
  }
}

TEST(Board, CharucoBoardFrameMatchesTheChessboard) {
  if (!CharucoSupported()) GTEST_SKIP() << "built without OpenCV's aruco module";
  Board board = sim::TestBoard();
  board.type = BoardType::kCharuco;
  board.square_mm = 20.0;
  board.marker_mm = 15.0;
  const CameraModel camera = IdealLens();
  for (double roll : {0.0, 180.0, 60.0}) {
    SCOPED_TRACE(roll);
    const Eigen::Isometry3d pose = Facing(board, roll, -20.0);
    Expected<cv::Mat> image = RenderBoard(camera, pose, board);
    ASSERT_TRUE(image) << image.error().ToString();
    Expected<Detection> d = DetectBoard(*image, board);
    ASSERT_TRUE(d) << d.error().ToString();
    EXPECT_GE(d->size(), 40u);
    // OpenCV draws the ChArUco texture in whole pixels: a little less exact than ours.
    EXPECT_LT(MaxCornerError(*d, board, camera, pose), 0.4);
  }
}

TEST(Board, NoBoardInABlankImage) {
  const cv::Mat blank(576, 768, CV_8UC3, cv::Scalar(90, 90, 90));
  Expected<Detection> d = DetectBoard(blank, sim::TestBoard());
  ASSERT_FALSE(d);
  EXPECT_EQ(d.error().code, ErrorCode::kBadInput);
  EXPECT_NE(d.error().message.find("no chessboard of 9x6 inner corners found"), std::string::npos)
      << d.error().message;
  EXPECT_NE(d.error().message.find("in view"), std::string::npos);
}

TEST(Board, WrongBoardSizeSaysWhatWasFound) {
  Board printed = sim::TestBoard();
  printed.cols = 7;
  printed.rows = 5;
  Expected<cv::Mat> image = RenderBoard(IdealLens(), Facing(printed, 10.0, 20.0), printed);
  ASSERT_TRUE(image);
  Expected<Detection> d = DetectBoard(*image, sim::TestBoard());
  ASSERT_FALSE(d);
  EXPECT_NE(d.error().message.find("no chessboard of 9x6"), std::string::npos) << d.error().message;
  EXPECT_NE(d.error().message.find("one of 7x5"), std::string::npos) << d.error().message;
  EXPECT_NE(d.error().message.find("cols/rows"), std::string::npos) << d.error().message;
}

TEST(Board, RendererShowsTheBackOfATurnedBoard) {
  const Board board = sim::TestBoard();
  Eigen::Isometry3d pose = Facing(board, 0.0, 0.0);
  pose.linear() = pose.linear() * sim::Ry(180.0);  // seen from behind
  pose.translation() = Eigen::Vector3d(60.0, -40.0, 500.0);
  Expected<cv::Mat> image = RenderBoard(IdealLens(), pose, board);
  ASSERT_TRUE(image);
  EXPECT_FALSE(DetectBoard(*image, board));
  // A board reaching behind the camera cannot be rendered.
  pose.translation() = Eigen::Vector3d(0.0, 0.0, -10.0);
  EXPECT_FALSE(RenderBoard(IdealLens(), pose, board));
}

}  // namespace
}  // namespace revolve::calibrate
