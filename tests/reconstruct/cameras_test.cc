// Camera import (reconstruct/cameras/camera_file.h) and view preparation
// (reconstruct/cameras/views.h): parsing both --cameras formats, the checks on odd matrices, the
// thesis's orthographic view, back-projection, the depth-sign fix and the carving volume found
// from the silhouettes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <optional>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "reconstruct/cameras/camera_file.h"
#include "reconstruct/cameras/views.h"
#include "tests/reconstruct/sphere_scene.h"

namespace revolve::reconstruct {
namespace {

TEST(CameraFile, ParsesMiddleburyLines) {
  const Expected<CameraFile> file = ParseCameraFile(
      "2\n"
      "# a comment\n"
      "a.png 100 0 50 0 100 40 0 0 1  1 0 0 0 1 0 0 0 1  0 0 5\n"
      "\n"
      "b.png 100 0 50 0 100 40 0 0 1  0 0 1 0 1 0 -1 0 0  0 0 5  # trailing\n",
      "test_par.txt");
  ASSERT_TRUE(file.has_value()) << file.error().ToString();
  EXPECT_EQ(file->format, CameraFileFormat::kMiddlebury);
  ASSERT_EQ(file->cameras.size(), 2u);
  EXPECT_EQ(file->cameras[1].line, 5);
  // P = K [R t]: the point (0, 0, 0) projects at the principal point.
  View view;
  view.pixel_from_object = file->cameras[0].pixel_from_object;
  Eigen::Vector2d pixel;
  ASSERT_TRUE(view.Project(Eigen::Vector3d::Zero(), &pixel));
  EXPECT_NEAR(pixel.x(), 50.0, 1e-12);
  EXPECT_NEAR(pixel.y(), 40.0, 1e-12);
  EXPECT_EQ(file->Find("a.png"), &file->cameras[0]);
  EXPECT_EQ(file->Find("b.tif"), &file->cameras[1]);  // matched by name without extension
  EXPECT_EQ(file->Find("c.png"), nullptr);
}

TEST(CameraFile, ParsesProjectionMatrices) {
  const Expected<CameraFile> file =
      ParseCameraFile("v0 1 0 0 10 0 1 0 20 0 0 1 5\nv1 -2 0 0 -20 0 -2 0 -40 0 0 -2 -10\n", "p");
  ASSERT_TRUE(file.has_value()) << file.error().ToString();
  EXPECT_EQ(file->format, CameraFileFormat::kProjection);
  EXPECT_DOUBLE_EQ(file->cameras[1].pixel_from_object(0, 3), -20.0);
}

TEST(CameraFile, ErrorsNameTheLine) {
  const auto message = [](std::string_view text) {
    const Expected<CameraFile> file = ParseCameraFile(text, "cams.txt");
    return file ? std::string("(parsed)") : file.error().message;
  };
  EXPECT_NE(message("a 1 2 3\n").find("cams.txt:1"), std::string::npos);
  EXPECT_NE(message("a 1 0 0 0 0 1 0 0 0 0 1 1\nb 1 0 0 0 0 1 0 0 0 0 1 x\n").find("cams.txt:2"),
            std::string::npos);
  EXPECT_NE(message("3\na 1 0 0 0 0 1 0 0 0 0 1 1\n").find("says 3"), std::string::npos);
  EXPECT_NE(message("a 1 0 0 0 0 1 0 0 0 0 1 1\na 1 0 0 0 0 1 0 0 0 0 1 1\n").find("twice"),
            std::string::npos);
  EXPECT_NE(message("a 1 0 0 0 2 0 0 0 0 0 0 1\n").find("degenerate"), std::string::npos);
  EXPECT_NE(message("# nothing\n").find("no camera"), std::string::npos);
  EXPECT_NE(message("a 1 0 0 0 0 1 0 0 0 0 1 1\n"
                    "b 1 0 0 0 1 0 0 0 1 1 0 0 0 1 0 0 0 1 0 0 1\n")
                .find("one format"),
            std::string::npos);
  const Expected<CameraFile> missing = ReadCameraFile("/nonexistent/cams.txt");
  ASSERT_FALSE(missing.has_value());
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  EXPECT_NE(missing.error().message.find("/nonexistent/cams.txt"), std::string::npos);
}

TEST(CameraFile, ViewsForImagesNeedsACameraPerImage) {
  const Expected<CameraFile> file =
      ParseCameraFile("a.png 1 0 0 0 0 1 0 0 0 0 1 1\nb.png 1 0 0 0 0 1 0 0 0 0 1 1\n", "f.txt");
  ASSERT_TRUE(file.has_value());
  EXPECT_TRUE(ViewsForImages(*file, {"a.png", "b.png"}, 64, 48).has_value());
  const Expected<std::vector<View>> short_of_cameras =
      ViewsForImages(*file, {"a.png", "b.png", "c.png"}, 64, 48);
  ASSERT_FALSE(short_of_cameras.has_value());
  EXPECT_NE(short_of_cameras.error().message.find("c.png"), std::string::npos);
  EXPECT_NE(short_of_cameras.error().message.find("f.txt"), std::string::npos);
}

TEST(ProjectionCheck, SplitsAPinholeAndReportsOddities) {
  Eigen::Matrix3d k;
  k << 800, 4, 320, 0, 820, 240, 0, 0, 1;
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(0.1, -0.2, 2.0);
  Matrix34d p;
  p.leftCols<3>() = 3.0 * k * r;
  p.col(3) = 3.0 * k * t;
  const ProjectionCheck check = CheckProjection(p);
  EXPECT_FALSE(check.affine);
  EXPECT_FALSE(check.mirrored);
  EXPECT_TRUE(check.K.isApprox(k, 1e-9));
  EXPECT_TRUE(check.R.isApprox(r, 1e-9));
  EXPECT_TRUE(check.t.isApprox(t, 1e-9));
  EXPECT_NE(check.oddities.find("skew"), std::string::npos);
  EXPECT_NE(check.oddities.find("aspect"), std::string::npos);
  // A mirrored frame: one axis of R flipped.
  Eigen::Matrix3d mirror = r;
  mirror.row(0) *= -1.0;
  p.leftCols<3>() = k * mirror;
  EXPECT_TRUE(CheckProjection(p).mirrored);
  EXPECT_TRUE(CheckProjection(ThesisView(64, 48, 0.0).pixel_from_object).affine);
}

TEST(ThesisView, AxisOnTheMiddleColumnRowsGiveHeight) {
  const View view = ThesisView(768, 576, 0.0);
  EXPECT_TRUE(view.IsAffine());
  Eigen::Vector2d pixel;
  ASSERT_TRUE(view.Project(Eigen::Vector3d(0.0, 0.0, 0.0), &pixel));
  EXPECT_DOUBLE_EQ(pixel.x(), 383.5);
  EXPECT_DOUBLE_EQ(pixel.y(), 575.0);
  // Eq. 4.9-4.11: the point at radius r on the meridian facing the camera at plate angle theta.
  const double theta = 30.0 * M_PI / 180.0;
  const double r = -100.0;  // left of the axis
  const View turned = ThesisView(768, 576, 30.0);
  ASSERT_TRUE(
      turned.Project(Eigen::Vector3d(r * std::cos(theta), -r * std::sin(theta), 200.0), &pixel));
  EXPECT_NEAR(pixel.x(), 383.5 + r, 1e-9);
  EXPECT_NEAR(pixel.y(), 575.0 - 200.0, 1e-9);
  // The camera lies on the table's -y side.
  EXPECT_TRUE(view.DirectionToCamera(Eigen::Vector3d::Zero()).isApprox(-Eigen::Vector3d::UnitY()));
}

TEST(BackProject, RaysProjectBackOntoTheirPixel) {
  const Rig rig = testing::StationRig();
  const View pinhole = testing::ViewOf(rig, 40.0);
  for (const View& view : {pinhole, ThesisView(640, 480, 25.0)}) {
    const std::optional<Ray> ray = BackProject(view, Eigen::Vector2d(100.0, 200.0));
    ASSERT_TRUE(ray.has_value());
    for (const double s : {10.0, 300.0}) {
      Eigen::Vector2d pixel;
      ASSERT_TRUE(view.Project(ray->origin + s * ray->direction, &pixel));
      EXPECT_NEAR(pixel.x(), 100.0, 1e-6);
      EXPECT_NEAR(pixel.y(), 200.0, 1e-6);
    }
  }
  // Depth grows along a pinhole ray.
  const std::optional<Ray> ray = BackProject(pinhole, Eigen::Vector2d(10.0, 20.0));
  EXPECT_GT(Depth(pinhole, ray->origin + ray->direction), Depth(pinhole, ray->origin));
}

TEST(NormaliseViewSign, FlipsOnlyWhenTheCentreIsBehind) {
  const Rig rig = testing::StationRig();
  View view = testing::ViewOf(rig, 0.0);
  View negated = view;
  negated.pixel_from_object *= -1.0;
  const Eigen::Vector3d centre(0.0, 0.0, 40.0);
  EXPECT_TRUE(
      NormaliseViewSign(negated, centre).pixel_from_object.isApprox(view.pixel_from_object));
  EXPECT_TRUE(NormaliseViewSign(view, centre).pixel_from_object.isApprox(view.pixel_from_object));
}

// The centre is the least-squares point of the rays through the silhouettes' centroids, as
// cv::moments finds them, on masks wider than the blocks the moments are summed in.
TEST(SilhouetteCentre, RaysThroughTheCentroidsOfWideMasks) {
  std::vector<cv::Mat> masks;
  std::vector<View> views;
  Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) {
    cv::Mat mask = cv::Mat::zeros(120, 9000, CV_8UC1);
    cv::ellipse(mask, cv::Point(4100 + 300 * k, 60), cv::Size(900 + 50 * k, 40), 0.0, 0.0, 360.0,
                cv::Scalar(255), cv::FILLED);
    cv::line(mask, cv::Point(8990, 3 + k), cv::Point(100, 90), cv::Scalar(7 + k));
    masks.push_back(mask);
    views.push_back(ThesisView(mask.cols, mask.rows, 50.0 * k));
    const cv::Moments m = cv::moments(mask, /*binaryImage=*/true);
    const std::optional<Ray> ray =
        BackProject(views.back(), Eigen::Vector2d(m.m10 / m.m00, m.m01 / m.m00));
    ASSERT_TRUE(ray.has_value());
    const Eigen::Matrix3d projector =
        Eigen::Matrix3d::Identity() - ray->direction * ray->direction.transpose();
    normal += projector;
    rhs += projector * ray->origin;
  }
  const Expected<Eigen::Vector3d> centre = SilhouetteCentre(masks, views);
  ASSERT_TRUE(centre.has_value()) << centre.error().ToString();
  const Eigen::Vector3d expected = normal.ldlt().solve(rhs);
  EXPECT_NEAR((*centre - expected).norm(), 0.0, 1e-9 * expected.norm());
}
TEST(CarvingVolume, FoundFromSilhouettesWhateverTheSigns) {
  const Rig rig = testing::StationRig(450.0, 10.0, 40.0);
  const testing::Sphere sphere{Eigen::Vector3d(10.0, -5.0, 45.0), 30.0};
  std::vector<cv::Mat> masks;
  std::vector<View> views;
  for (int k = 0; k < 12; ++k) {
    masks.push_back(testing::SphereMask(rig, 30.0 * k, sphere));
    View view = testing::ViewOf(rig, 30.0 * k);
    if (k % 3 == 0) view.pixel_from_object *= -4.0;  // any scale, any sign
    views.push_back(view);
  }
  const Expected<AutoVolume> volume = CarvingVolumeFromSilhouettes(masks, views);
  ASSERT_TRUE(volume.has_value()) << volume.error().ToString();
  EXPECT_LT((volume->centre - sphere.centre_mm).norm(), 3.0);
  for (int a = 0; a < 3; ++a) {
    EXPECT_LE(volume->box.min[a], sphere.centre_mm[a] - sphere.radius_mm);
    EXPECT_GE(volume->box.max[a], sphere.centre_mm[a] + sphere.radius_mm);
    // The hull of 12 views at 10 deg elevation overshoots at the poles; not much elsewhere.
    EXPECT_GE(volume->box.min[a], sphere.centre_mm[a] - 1.25 * sphere.radius_mm);
    EXPECT_LE(volume->box.max[a], sphere.centre_mm[a] + 1.25 * sphere.radius_mm);
  }
  EXPECT_FALSE(volume->touches_limit);
  // Empty silhouettes: an error, not a volume.
  std::vector<cv::Mat> empty(masks.size(), cv::Mat(masks[0].size(), CV_8UC1, cv::Scalar(0)));
  EXPECT_FALSE(CarvingVolumeFromSilhouettes(empty, views).has_value());
}

// One mask that lost the lower half of the object (a shadow cut away in one frame): the box still
// holds the whole object, so the silhouette consensus can find that mask out; trusting every mask
// (tolerated_misses 0) cuts the box short.
TEST(CarvingVolume, OneMaskMissingAPartDoesNotCutTheBox) {
  const Rig rig = testing::StationRig(450.0, 10.0, 40.0);
  const testing::Sphere sphere{Eigen::Vector3d(0.0, 0.0, 45.0), 30.0};
  std::vector<cv::Mat> masks;
  std::vector<View> views;
  for (int k = 0; k < 12; ++k) {
    masks.push_back(testing::SphereMask(rig, 30.0 * k, sphere));
    views.push_back(testing::ViewOf(rig, 30.0 * k));
  }
  const cv::Rect box = cv::boundingRect(masks[4]);
  masks[4](
      cv::Rect(0, box.y + box.height / 2, masks[4].cols, masks[4].rows - box.y - box.height / 2))
      .setTo(0);
  const Expected<AutoVolume> tolerant = CarvingVolumeFromSilhouettes(masks, views);
  ASSERT_TRUE(tolerant.has_value()) << tolerant.error().ToString();
  EXPECT_LE(tolerant->box.min.z(), sphere.centre_mm.z() - sphere.radius_mm);
  AutoVolumeOptions trusting;
  trusting.tolerated_misses = 0;
  const Expected<AutoVolume> strict = CarvingVolumeFromSilhouettes(masks, views, trusting);
  ASSERT_TRUE(strict.has_value()) << strict.error().ToString();
  EXPECT_GT(strict->box.min.z(), sphere.centre_mm.z() - 0.5 * sphere.radius_mm);
}

// A small sphere beside a large one, level with its middle: the layers through it have their
// widest rows in the middle, not at their ends. The box reaches out to the small sphere (the
// search tests every row's cells outside the range found so far), and not beyond.
TEST(CarvingVolume, ReachesAPartThatWidensTheMiddleRows) {
  const Rig rig = testing::StationRig(450.0, 10.0, 40.0);
  const testing::Sphere large{Eigen::Vector3d(0.0, 0.0, 45.0), 25.0};
  const testing::Sphere small{Eigen::Vector3d(36.0, 0.0, 45.0), 8.0};
  std::vector<cv::Mat> masks;
  std::vector<View> views;
  for (int k = 0; k < 12; ++k) {
    masks.push_back(testing::SphereMask(rig, 30.0 * k, std::vector<testing::Sphere>{large, small}));
    views.push_back(testing::ViewOf(rig, 30.0 * k));
  }
  const Expected<AutoVolume> volume = CarvingVolumeFromSilhouettes(masks, views);
  ASSERT_TRUE(volume.has_value()) << volume.error().ToString();
  EXPECT_GE(volume->box.max.x(), small.centre_mm.x() + small.radius_mm);
  EXPECT_LE(volume->box.max.x(), small.centre_mm.x() + 2.0 * small.radius_mm);
  EXPECT_LE(volume->box.min.x(), large.centre_mm.x() - large.radius_mm);
  EXPECT_GE(volume->box.min.x(), large.centre_mm.x() - 1.25 * large.radius_mm);
  for (const double y : {volume->box.min.y(), volume->box.max.y()}) {
    EXPECT_GE(std::abs(y), large.radius_mm);
    EXPECT_LE(std::abs(y), 1.25 * large.radius_mm);
  }
}

// Passing over blocks of cells that fall for certain finds the volume testing every cell finds,
// to the bit: objects off the turntable's axis, apart or one, a mask missing a part, views at
// any scale and sign, with and without a tolerated miss.
TEST(CarvingVolume, BlocksPassedOverGiveTheVolumeOfEveryCell) {
  const Rig rig = testing::StationRig(450.0, 10.0, 40.0);
  const std::vector<std::vector<testing::Sphere>> scenes = {
      {{Eigen::Vector3d(10.0, -5.0, 45.0), 30.0}},
      {{Eigen::Vector3d(0.0, 0.0, 45.0), 25.0}, {Eigen::Vector3d(36.0, 0.0, 45.0), 8.0}},
      {{Eigen::Vector3d(-20.0, 15.0, 30.0), 12.0}, {Eigen::Vector3d(25.0, -10.0, 70.0), 15.0}}};
  for (std::size_t s = 0; s < scenes.size(); ++s) {
    for (const int count : {12, 36}) {
      std::vector<cv::Mat> masks;
      std::vector<View> views;
      for (int k = 0; k < count; ++k) {
        const double angle = 360.0 * k / count;
        masks.push_back(testing::SphereMask(rig, angle, scenes[s]));
        View view = testing::ViewOf(rig, angle);
        if (k % 5 == 0) view.pixel_from_object *= -3.0;
        views.push_back(view);
      }
      const cv::Rect box = cv::boundingRect(masks[2]);
      masks[2](cv::Rect(0, box.y + box.height / 2, masks[2].cols,
                        masks[2].rows - box.y - box.height / 2))
          .setTo(0);
      for (const int tolerated : {0, 1}) {
        AutoVolumeOptions blocks;
        blocks.tolerated_misses = tolerated;
        AutoVolumeOptions every = blocks;
        every.block_tests = false;
        const Expected<AutoVolume> fast = CarvingVolumeFromSilhouettes(masks, views, blocks);
        const Expected<AutoVolume> slow = CarvingVolumeFromSilhouettes(masks, views, every);
        ASSERT_TRUE(fast.has_value() && slow.has_value()) << s;
        EXPECT_EQ(std::memcmp(fast->box.min.data(), slow->box.min.data(), 3 * sizeof(double)), 0)
            << s << " " << count << " " << tolerated;
        EXPECT_EQ(std::memcmp(fast->box.max.data(), slow->box.max.data(), 3 * sizeof(double)), 0)
            << s << " " << count << " " << tolerated;
        EXPECT_EQ(fast->touches_limit, slow->touches_limit);
      }
    }
  }
}

// Masks held as windows of their images (the silhouette's rectangle, tight or with a margin cut
// by the image's border, the whole image, an empty mask's empty window) give the centre and the
// volume the whole masks give, to the bit.
TEST(CarvingVolume, WindowsOfTheMasksGiveTheVolumeOfTheWholeMasks) {
  const Rig rig = testing::StationRig(450.0, 10.0, 40.0);
  const std::vector<testing::Sphere> scene = {{Eigen::Vector3d(0.0, 0.0, 45.0), 25.0},
                                              {Eigen::Vector3d(36.0, 0.0, 45.0), 8.0}};
  std::vector<cv::Mat> masks;
  std::vector<View> views;
  for (int k = 0; k < 36; ++k) {
    masks.push_back(testing::SphereMask(rig, 10.0 * k, scene));
    View view = testing::ViewOf(rig, 10.0 * k);
    if (k % 5 == 0) view.pixel_from_object *= -3.0;
    views.push_back(view);
  }
  // With one miss tolerated, a view whose mask is empty (its window too).
  for (const int tolerated : {0, 1}) {
    if (tolerated == 1) masks[7].setTo(0);
    std::vector<cv::Mat> windows;
    std::vector<cv::Point> origins;
    for (std::size_t i = 0; i < masks.size(); ++i) {
      const cv::Rect image(cv::Point(), masks[i].size());
      const cv::Rect tight = cv::boundingRect(masks[i]);
      const int margin = i % 3 == 0 ? 0 : 40;
      const cv::Rect window = i == 4 ? image
                              : tight.empty()
                                  ? cv::Rect()
                                  : cv::Rect(tight.x - margin, tight.y - margin,
                                             tight.width + 2 * margin, tight.height + 2 * margin) &
                                        image;
      windows.push_back(masks[i](window).clone());
      origins.push_back(window.tl());
    }
    const Expected<Eigen::Vector3d> whole_centre = SilhouetteCentre(masks, views);
    const Expected<Eigen::Vector3d> window_centre = SilhouetteCentre(windows, views, origins);
    ASSERT_TRUE(whole_centre.has_value() && window_centre.has_value());
    EXPECT_EQ(std::memcmp(whole_centre->data(), window_centre->data(), 3 * sizeof(double)), 0);
    AutoVolumeOptions options;
    options.tolerated_misses = tolerated;
    const Expected<AutoVolume> whole = CarvingVolumeFromSilhouettes(masks, views, options);
    const Expected<AutoVolume> held =
        CarvingVolumeFromSilhouettes(windows, views, options, origins);
    ASSERT_TRUE(whole.has_value() && held.has_value()) << tolerated;
    EXPECT_EQ(std::memcmp(whole->box.min.data(), held->box.min.data(), 3 * sizeof(double)), 0);
    EXPECT_EQ(std::memcmp(whole->box.max.data(), held->box.max.data(), 3 * sizeof(double)), 0);
    EXPECT_EQ(whole->touches_limit, held->touches_limit);
    // A window reaching out of its image is refused.
    std::vector<cv::Point> outside = origins;
    outside[3] = cv::Point(masks[3].cols - windows[3].cols / 2, 0);
    EXPECT_FALSE(CarvingVolumeFromSilhouettes(windows, views, options, outside).has_value());
  }
}

}  // namespace
}  // namespace revolve::reconstruct
