// The thesis's meridian method on analytic silhouettes: a vase-shaped surface of revolution in the
// calibration-free (orthographic, pixel units) mode, 36 views at 10 deg, and a sphere seen by the
// calibrated station rig.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>

#include <unistd.h>

#include <opencv2/imgproc.hpp>

#include "reconstruct/cameras/views.h"
#include "reconstruct/meridian/meridian.h"
#include "reconstruct/meridian/meridian_vrml.h"
#include "reconstruct/metrics/metrics.h"
#include "reconstruct/metrics/reprojection.h"
#include "reconstruct/reconstructor.h"
#include "reconstruct/texture/view_atlas.h"
#include "tests/reconstruct/sphere_scene.h"

namespace revolve::reconstruct {
namespace {

constexpr int kWidth = 768;
constexpr int kHeight = 576;

// A vase: radius (px) as a function of height z (px above the bottom row), for z in
// [kBottom, kTop].
constexpr double kBottom = 30.0;
constexpr double kTop = 520.0;
double VaseRadius(double z) {
  const double t = (z - kBottom) / (kTop - kBottom);
  return 95.0 + 75.0 * std::sin(std::numbers::pi * (0.15 + 1.2 * t)) -
         30.0 * std::sin(3.0 * std::numbers::pi * t) * t;
}
double LargestRadius() {
  double r = 0.0;
  for (double z = kBottom; z <= kTop; z += 0.25) r = std::max(r, VaseRadius(z));
  return r;
}

// The silhouette of the vase in the thesis's view: a surface of revolution about the axis looks
// the same from every angle (pixel centre inside iff |u - u0| < radius at its row's height).
cv::Mat VaseMask() {
  cv::Mat mask(kHeight, kWidth, CV_8UC1, cv::Scalar(0));
  const double u0 = 0.5 * (kWidth - 1);
  for (int v = 0; v < kHeight; ++v) {
    const double z = (kHeight - 1) - v;
    if (z < kBottom || z > kTop) continue;
    const double r = VaseRadius(z);
    for (int u = 0; u < kWidth; ++u) {
      if (std::abs(u - u0) < r) mask.at<std::uint8_t>(v, u) = 255;
    }
  }
  return mask;
}

// A photo for texture: the view's number in its colour, so each strip's source can be told.
cv::Mat ViewPhoto(const cv::Mat& mask, int view) {
  cv::Mat photo(mask.size(), CV_8UC3, cv::Scalar(0, 0, 0));
  photo.setTo(cv::Scalar(40 + 5 * view, 255 - 5 * view, 128), mask);
  return photo;
}

struct RadialError {
  double mean = 0.0;
  double max = 0.0;
};

// |sqrt(x^2 + y^2) - radius(z)| over the mesh's meridian vertices (the axis points of the caps
// left out) and over points sampled on its side triangles.
RadialError VertexRadialError(const Mesh& mesh) {
  RadialError e;
  int n = 0;
  for (const Eigen::Vector3f& p : mesh.vertices) {
    const double r = p.head<2>().cast<double>().norm();
    if (r < 1e-6) continue;
    const double err = std::abs(r - VaseRadius(p.z()));
    e.mean += err;
    e.max = std::max(e.max, err);
    ++n;
  }
  e.mean /= std::max(n, 1);
  return e;
}

RadialError SurfaceRadialError(const Mesh& mesh) {
  RadialError e;
  int n = 0;
  for (const Eigen::Vector3i& f : mesh.faces) {
    const Eigen::Vector3d a = mesh.vertices[f[0]].cast<double>();
    const Eigen::Vector3d b = mesh.vertices[f[1]].cast<double>();
    const Eigen::Vector3d c = mesh.vertices[f[2]].cast<double>();
    if (a.head<2>().norm() < 1e-6 || b.head<2>().norm() < 1e-6 || c.head<2>().norm() < 1e-6) {
      continue;  // a cap
    }
    for (const auto& [wa, wb] : {std::pair{1.0 / 3, 1.0 / 3}, std::pair{0.6, 0.2},
                                 std::pair{0.2, 0.6}, std::pair{0.2, 0.2}}) {
      const Eigen::Vector3d p = wa * a + wb * b + (1.0 - wa - wb) * c;
      const double err = std::abs(p.head<2>().norm() - VaseRadius(p.z()));
      e.mean += err;
      e.max = std::max(e.max, err);
      ++n;
    }
  }
  e.mean /= std::max(n, 1);
  return e;
}

Expected<MeridianModel> ReconstructVase(const MeridianOptions& options, int views, double step_deg,
                                        bool photos) {
  MeridianReconstructor reconstructor(options);
  const cv::Mat mask = VaseMask();
  for (int k = 0; k < views; ++k) {
    const Expected<void> done = reconstructor.Integrate(
        mask, photos ? ViewPhoto(mask, k) : cv::Mat(), ThesisView(kWidth, kHeight, k * step_deg));
    if (!done) return std::unexpected(done.error());
  }
  return reconstructor.FinishModel();
}

TEST(Meridian, VaseThesisModeRadialErrorIsUnderHalfAPercent) {
  const Expected<MeridianModel> model = ReconstructVase(MeridianOptions{}, 36, 10.0, false);
  ASSERT_TRUE(model.has_value()) << model.error().ToString();
  EXPECT_EQ(model->meridian_count, 36);
  const MeshStats stats = ComputeStats(model->mesh);
  EXPECT_TRUE(stats.closed);
  EXPECT_TRUE(stats.oriented);
  EXPECT_GT(stats.volume_mm3, 0.0);
  const double largest = LargestRadius();
  const RadialError vertices = VertexRadialError(model->mesh);
  const RadialError surface = SurfaceRadialError(model->mesh);
  std::printf(
      "vase, 36 views, rows every 9 px: %d rows; radial error at feature points mean "
      "%.3f px (%.3f%% of %.1f px) max %.3f px; on the strips mean %.3f px (%.3f%%) max "
      "%.3f px\n",
      model->row_count, vertices.mean, 100.0 * vertices.mean / largest, largest, vertices.max,
      surface.mean, 100.0 * surface.mean / largest, surface.max);
  EXPECT_LE(vertices.mean, 0.005 * largest);
  EXPECT_LE(surface.mean, 0.005 * largest);
  EXPECT_LE(vertices.max, 0.5 + 1e-6);  // the half-pixel of the silhouette's quantisation
  // The height runs from the bottom row of the vase to its top (rows every 9 px, and the last).
  EXPECT_NEAR(stats.bbox_max_mm.z(), kTop, 1.0);
  EXPECT_NEAR(stats.bbox_min_mm.z(), kBottom, 1.0);
  RecordProperty("mean_radial_error_percent", std::to_string(100.0 * vertices.mean / largest));
}

TEST(Meridian, BothSidesModeNeedsHalfTheViews) {
  MeridianOptions options;
  options.both_sides = true;
  const Expected<MeridianModel> half = ReconstructVase(options, 18, 10.0, false);
  ASSERT_TRUE(half.has_value()) << half.error().ToString();
  EXPECT_EQ(half->meridian_count, 36);
  const MeshStats stats = ComputeStats(half->mesh);
  EXPECT_TRUE(stats.closed);
  EXPECT_TRUE(stats.oriented);
  EXPECT_LE(VertexRadialError(half->mesh).mean, 0.005 * LargestRadius());
  // All 36 views in both-sides mode: the right meridians duplicate left ones and are dropped.
  const Expected<MeridianModel> full = ReconstructVase(options, 36, 10.0, false);
  ASSERT_TRUE(full.has_value());
  EXPECT_EQ(full->meridian_count, 36);
  // 18 views at 20 deg, one side: 18 meridians (the thesis's other sequence).
  const Expected<MeridianModel> coarse = ReconstructVase(MeridianOptions{}, 18, 20.0, false);
  ASSERT_TRUE(coarse.has_value());
  EXPECT_EQ(coarse->meridian_count, 18);
  EXPECT_LE(SurfaceRadialError(coarse->mesh).mean, 0.01 * LargestRadius());
}

TEST(Meridian, StripsAreTexturedFromTheViewFacingThem) {
  const Expected<MeridianModel> model = ReconstructVase(MeridianOptions{}, 36, 10.0, true);
  ASSERT_TRUE(model.has_value()) << model.error().ToString();
  ASSERT_TRUE(model->HasTexture());
  ASSERT_EQ(model->mesh.view_texture.uv_faces.size(), model->mesh.faces.size());
  int textured = 0;
  for (std::size_t f = 0; f < model->mesh.faces.size(); ++f) {
    const int t = model->mesh.view_texture.face_image[f];
    if (t < 0) continue;
    ++textured;
    ASSERT_LT(t, static_cast<int>(model->mesh.view_texture.images.size()));
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector2f& uv =
          model->mesh.view_texture
              .uvs[static_cast<std::size_t>(model->mesh.view_texture.uv_faces[f][k])];
      EXPECT_GE(uv.minCoeff(), 0.0f);
      EXPECT_LE(uv.maxCoeff(), 1.0f);
    }
  }
  // Side strips are textured (the caps, seen edge-on by level cameras, are not).
  EXPECT_EQ(textured, 2 * model->meridian_count * (model->row_count - 1));
  // Each strip's texture coordinates land on the object in its image: sample the texture at the
  // centroid of every textured triangle and find the object's colour, not the black background.
  int on_object = 0;
  for (std::size_t f = 0; f < model->mesh.faces.size(); ++f) {
    const int t = model->mesh.view_texture.face_image[f];
    if (t < 0) continue;
    Eigen::Vector2f uv = Eigen::Vector2f::Zero();
    for (int k = 0; k < 3; ++k)
      uv += model->mesh.view_texture
                .uvs[static_cast<std::size_t>(model->mesh.view_texture.uv_faces[f][k])];
    uv /= 3.0f;
    const cv::Mat& image = model->mesh.view_texture.images[static_cast<std::size_t>(t)];
    const int u = std::clamp(static_cast<int>(uv.x() * image.cols), 0, image.cols - 1);
    const int v = std::clamp(static_cast<int>((1.0f - uv.y()) * image.rows), 0, image.rows - 1);
    on_object += image.at<cv::Vec3b>(v, u)[1] > 0;
  }
  EXPECT_EQ(on_object, textured);

  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("revolve_meridian_test_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const Expected<std::vector<std::filesystem::path>> files =
      WriteTexturedVrml(model->mesh, dir / "vase.wrl", 1.0);
  ASSERT_TRUE(files.has_value()) << files.error().ToString();
  EXPECT_EQ(files->size(), model->mesh.view_texture.images.size() + 1);
  EXPECT_EQ(files->back(), dir / "vase.wrl");
  const Expected<std::vector<std::string>> urls = ReadVrmlTextureUrls(dir / "vase.wrl");
  ASSERT_TRUE(urls.has_value()) << urls.error().ToString();
  ASSERT_EQ(urls->size(), model->mesh.view_texture.images.size());
  for (const std::string& url : *urls) EXPECT_TRUE(std::filesystem::exists(dir / url)) << url;
  std::ifstream in(dir / "vase.wrl");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const char* node :
       {"#VRML V2.0 utf8", "Shape", "Appearance", "Material", "ImageTexture", "IndexedFaceSet",
        "Coordinate", "TextureCoordinate", "coordIndex", "texCoordIndex", "NavigationInfo"}) {
    EXPECT_NE(text.find(node), std::string::npos) << node;
  }
  std::filesystem::remove_all(dir);
}

// The atlas OBJ and glTF carry holds the view-dependent texture's pixels: every face samples the
// same colour at its centroid in the atlas as in its view's image; untextured faces are grey.
TEST(Meridian, AtlasHoldsTheViewDependentTexture) {
  const Expected<MeridianModel> model = ReconstructVase(MeridianOptions{}, 36, 10.0, true);
  ASSERT_TRUE(model.has_value()) << model.error().ToString();
  const Mesh& mesh = model->mesh;
  ASSERT_TRUE(mesh.HasTexture());
  EXPECT_LE(std::max(mesh.texture.cols, mesh.texture.rows), 4096);
  // Strips are narrow: the atlas is far smaller than the frames it comes from.
  EXPECT_LT(mesh.texture.total(),
            mesh.view_texture.images.size() * mesh.view_texture.images[0].total() / 4);
  const ViewTexture& vt = mesh.view_texture;
  int compared = 0;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    Eigen::Vector2f atlas_uv = Eigen::Vector2f::Zero();
    for (int k = 0; k < 3; ++k) atlas_uv += mesh.uvs[static_cast<std::size_t>(mesh.uv_faces[f][k])];
    atlas_uv /= 3.0f;
    const cv::Vec3b in_atlas =
        mesh.texture.at<cv::Vec3b>(static_cast<int>(atlas_uv.y() * mesh.texture.rows),
                                   static_cast<int>(atlas_uv.x() * mesh.texture.cols));
    const int t = vt.face_image[f];
    if (t < 0) {
      EXPECT_EQ(in_atlas, cv::Vec3b(204, 204, 204));
      continue;
    }
    Eigen::Vector2f uv = Eigen::Vector2f::Zero();
    for (int k = 0; k < 3; ++k) uv += vt.uvs[static_cast<std::size_t>(vt.uv_faces[f][k])];
    uv /= 3.0f;
    const cv::Mat& image = vt.images[static_cast<std::size_t>(t)];
    const cv::Vec3b in_view = image.at<cv::Vec3b>(static_cast<int>((1.0f - uv.y()) * image.rows),
                                                  static_cast<int>(uv.x() * image.cols));
    EXPECT_EQ(in_atlas, in_view) << "face " << f;
    ++compared;
  }
  EXPECT_EQ(compared, 2 * model->meridian_count * (model->row_count - 1));

  // A small atlas bound scales the patches down to fit.
  Mesh small = mesh;
  ASSERT_TRUE(AtlasFromViewTexture(&small, 256).has_value());
  EXPECT_LE(std::max(small.texture.cols, small.texture.rows), 256);
  EXPECT_FALSE(AtlasFromViewTexture(&small, 10).has_value());
  Mesh plain = mesh;
  plain.view_texture = {};
  EXPECT_FALSE(AtlasFromViewTexture(&plain, 1024).has_value());
}

TEST(Meridian, CreateDispatchesAndChecksItsInput) {
  ReconstructOptions options;
  options.method = "meridian";
  Expected<std::unique_ptr<Reconstructor>> reconstructor = Create(options);
  ASSERT_TRUE(reconstructor.has_value()) << reconstructor.error().ToString();
  const View view = ThesisView(kWidth, kHeight, 0.0);
  EXPECT_FALSE((*reconstructor)->Integrate(cv::Mat(10, 10, CV_8UC1), cv::Mat(), view).has_value());
  const cv::Mat empty(kHeight, kWidth, CV_8UC1, cv::Scalar(0));
  for (int k = 0; k < 4; ++k) {
    ASSERT_TRUE(
        (*reconstructor)->Integrate(empty, cv::Mat(), ThesisView(kWidth, kHeight, 90.0 * k)));
  }
  const Expected<Mesh> mesh = (*reconstructor)->Finish();
  ASSERT_FALSE(mesh.has_value());
  EXPECT_NE(mesh.error().message.find("empty"), std::string::npos) << mesh.error().message;
  options.meridian_row_step_px = 0;
  EXPECT_FALSE(Create(options).has_value());
}

TEST(Meridian, SphereOnTheCalibratedRig) {
  // The station rig (perspective, 450 mm away, level camera): the ray through the silhouette's
  // edge passes closest to the axis near the true contour.
  const Rig rig = testing::StationRig(450.0, 0.0, 40.0);
  const testing::Sphere sphere;
  MeridianReconstructor reconstructor(MeridianOptions{4, false});
  for (int k = 0; k < 36; ++k) {
    ASSERT_TRUE(reconstructor.Integrate(testing::SphereMask(rig, 10.0 * k, sphere), cv::Mat(),
                                        testing::ViewOf(rig, 10.0 * k)));
  }
  const Expected<Mesh> mesh = reconstructor.Finish();
  ASSERT_TRUE(mesh.has_value()) << mesh.error().ToString();
  const MeshStats stats = ComputeStats(*mesh);
  EXPECT_TRUE(stats.closed);
  EXPECT_TRUE(stats.oriented);
  const SphereFit fit = FitSphere(*mesh);
  std::printf(
      "sphere r = 40 mm on the station rig: fitted r = %.3f mm, centre off %.3f mm, "
      "volume %.1f%%\n",
      fit.radius_mm, (fit.centre_mm - sphere.centre_mm).norm(),
      100.0 * (stats.volume_mm3 / (4.0 / 3.0 * std::numbers::pi * 40.0 * 40.0 * 40.0) - 1.0));
  EXPECT_NEAR(fit.radius_mm, sphere.radius_mm, 0.02 * sphere.radius_mm);
  EXPECT_LT((fit.centre_mm - sphere.centre_mm).norm(), 0.02 * sphere.radius_mm);
}

}  // namespace
}  // namespace revolve::reconstruct
