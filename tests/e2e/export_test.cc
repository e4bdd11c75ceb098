// `revolve export`: a scan of the simulated rig as a COLMAP text workspace and a nerfstudio
// transforms.json, checked three ways:
//  - by an independent reading of the formats' conventions (parsed here, not with revolve's
//    writer: COLMAP's Hamilton quaternion world-to-camera poses and its pixel corner at (0, 0);
//    nerfstudio's OpenGL camera-to-world matrices): the scan's hull projected through the
//    exported cameras covers the exported masks (mean IoU >= 0.98);
//  - by COLMAP itself (Debian's colmap, CPU only): model_converter reads the export, and SIFT
//    features (extracted inside the masks), matched exhaustively and triangulated with the
//    exported poses held fixed (point_triangulator), lie on the hull's surface (median < 1 mm);
//  - by the errors a user meets (thesis-mode scans, a wrong format).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <Eigen/Dense>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/synthetic/mesh.h"
#include "tests/support/test_files.h"

namespace fs = std::filesystem;

namespace {

using revolve::test_support::ReadAll;
using revolve::test_support::RunResult;

// Spot (Keenan Crane's cow, shared/data) when present, else the built-in vase; the synthetic
// camera paints its procedural texture on either. 12 stops of 640 x 480 px keep COLMAP quick.
std::string ScanConfig() {
  const fs::path spot = fs::path(REVOLVE_SHARED_DIR) / "data" / "meshes" / "spot.obj";
  const std::string object = fs::exists(spot)
                                 ? "object = \"mesh\"\nmesh_path = \"" + spot.string() + "\"\n"
                                 : "object = \"vase\"\nradius_mm = 35.0\n";
  return R"(
[scan]
stops = 12
step_deg = 30.0
settle_ms = 0

[turntable]
backend = "mock"
[turntable.mock]
time_scale = 0.01

[camera]
backend = "synthetic"
[camera.synthetic]
)" + object +
         R"(height_mm = 80.0
target_height_mm = 40.0
distance_mm = 320.0
elevation_deg = 20.0
width_px = 640
height_px = 480
noise_sigma = 1.0
texture = "speckle"

[reconstruct]
resolution = 160
volume_radius_mm = 60.0
volume_height_mm = 90.0
formats = ["ply"]
)";
}

struct Camera {
  std::string model;
  int width = 0;
  int height = 0;
  std::vector<double> params;
};

// An image's pose and name, read from images.txt.
struct Pose {
  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();  // cam_from_world
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  std::string name;
};

std::vector<std::string> DataLines(const fs::path& file) {
  std::istringstream in(ReadAll(file));
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line[0] == '#') continue;
    lines.push_back(line);
  }
  return lines;
}

// COLMAP's quaternion convention (Hamilton, w first), written out from its definition.
Eigen::Matrix3d RotationFromQuaternion(double w, double x, double y, double z) {
  Eigen::Matrix3d r;
  r << 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),  //
      2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),   //
      2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y);
  return r;
}

std::map<int, Camera> ReadCameras(const fs::path& file) {
  std::map<int, Camera> cameras;
  for (const std::string& line : DataLines(file)) {
    std::istringstream in(line);
    int id = 0;
    Camera c;
    if (!(in >> id >> c.model >> c.width >> c.height)) continue;
    for (double p; in >> p;) c.params.push_back(p);
    cameras[id] = c;
  }
  return cameras;
}

// images.txt: two lines per image (the second, 2D points, may be empty).
std::vector<Pose> ReadImages(const fs::path& file, int* camera_id) {
  std::vector<Pose> poses;
  const std::vector<std::string> lines = DataLines(file);
  for (std::size_t i = 0; i + 1 <= lines.size(); i += 2) {
    std::istringstream in(lines[i]);
    int id = 0;
    double qw, qx, qy, qz;
    Pose p;
    if (!(in >> id >> qw >> qx >> qy >> qz >> p.t.x() >> p.t.y() >> p.t.z() >> *camera_id >>
          p.name)) {
      ADD_FAILURE() << "bad images.txt line: " << lines[i];
      continue;
    }
    EXPECT_EQ(id, static_cast<int>(poses.size()) + 1);
    EXPECT_NEAR(qw * qw + qx * qx + qy * qy + qz * qz, 1.0, 1e-9);
    p.r = RotationFromQuaternion(qw, qx, qy, qz);
    poses.push_back(p);
  }
  return poses;
}

// The mesh drawn as a mask: pixels whose centre lies inside a projected triangle. `project`
// maps a world point to pixel coordinates with the image's top-left CORNER at (0, 0).
template <typename Project>
cv::Mat DrawMask(const revolve::capture::TriangleMesh& mesh, int width, int height,
                 const Project& project) {
  cv::Mat mask(height, width, CV_8UC1, cv::Scalar(0));
  for (const Eigen::Vector3i& t : mesh.triangles) {
    // Pixel centres: the corner convention minus 0.5.
    Eigen::Vector2d p[3];
    for (int c = 0; c < 3; ++c) p[c] = project(mesh.vertices[t[c]]) - Eigen::Vector2d(0.5, 0.5);
    const double area =
        (p[1] - p[0]).x() * (p[2] - p[0]).y() - (p[1] - p[0]).y() * (p[2] - p[0]).x();
    if (area == 0.0) continue;
    const int x0 =
        std::max(0, static_cast<int>(std::ceil(std::min({p[0].x(), p[1].x(), p[2].x()}))));
    const int x1 =
        std::min(width - 1, static_cast<int>(std::floor(std::max({p[0].x(), p[1].x(), p[2].x()}))));
    const int y0 =
        std::max(0, static_cast<int>(std::ceil(std::min({p[0].y(), p[1].y(), p[2].y()}))));
    const int y1 = std::min(height - 1,
                            static_cast<int>(std::floor(std::max({p[0].y(), p[1].y(), p[2].y()}))));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        bool inside = true;
        for (int e = 0; e < 3 && inside; ++e) {
          const Eigen::Vector2d& a = p[e];
          const Eigen::Vector2d& b = p[(e + 1) % 3];
          const double side = (b.x() - a.x()) * (y - a.y()) - (b.y() - a.y()) * (x - a.x());
          inside = area > 0.0 ? side >= 0.0 : side <= 0.0;
        }
        if (inside) mask.at<std::uint8_t>(y, x) = 255;
      }
    }
  }
  return mask;
}

double Iou(const cv::Mat& a, const cv::Mat& b) {
  const double inter = cv::countNonZero(a & b);
  const double uni = cv::countNonZero(a | b);
  return uni > 0 ? inter / uni : 0.0;
}

class ExportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = revolve::test_support::FreshTestDir("revolve_export");
    scan_ = dir_ / "scan";
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }

  RunResult Run(const std::string& command) {
    return revolve::test_support::RunShell(command, dir_);
  }
  RunResult Revolve(const std::string& args) { return Run(std::string(REVOLVE_BIN) + " " + args); }

  // Scans the simulated rig into dir_/scan and loads its hull.
  void Scan(const std::string& config_text = ScanConfig()) {
    std::ofstream(dir_ / "scan.toml") << config_text;
    const RunResult r =
        Revolve("scan --config " + (dir_ / "scan.toml").string() + " --out " + scan_.string());
    ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
    auto hull = revolve::capture::ReadMesh(scan_ / "model" / "model.ply");
    ASSERT_TRUE(hull.has_value()) << hull.error().message;
    hull_ = std::make_shared<revolve::capture::TriangleMesh>(std::move(*hull));
  }

  fs::path dir_;
  fs::path scan_;
  std::shared_ptr<revolve::capture::TriangleMesh> hull_;
};

TEST_F(ExportTest, ColmapCamerasProjectTheHullOntoTheMasks) {
  ASSERT_NO_FATAL_FAILURE(Scan());
  const fs::path out = dir_ / "colmap";
  const RunResult r =
      Revolve("export " + scan_.string() + " --format colmap --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;

  const std::map<int, Camera> cameras = ReadCameras(out / "sparse/0/cameras.txt");
  ASSERT_EQ(cameras.size(), 1u);
  const Camera& camera = cameras.begin()->second;
  EXPECT_EQ(camera.model, "PINHOLE") << "the scan's frames are undistorted";
  ASSERT_EQ(camera.params.size(), 4u);
  int camera_id = 0;
  const std::vector<Pose> poses = ReadImages(out / "sparse/0/images.txt", &camera_id);
  EXPECT_EQ(camera_id, cameras.begin()->first);
  ASSERT_EQ(poses.size(), 12u);
  EXPECT_TRUE(DataLines(out / "sparse/0/points3D.txt").empty());

  double iou_sum = 0.0;
  double iou_min = 1.0;
  for (const Pose& pose : poses) {
    SCOPED_TRACE(pose.name);
    const cv::Mat image = cv::imread((out / "images" / pose.name).string());
    ASSERT_FALSE(image.empty());
    EXPECT_EQ(image.cols, camera.width);
    EXPECT_EQ(image.rows, camera.height);
    // COLMAP's mask convention: the image's full name plus .png, zero = ignore.
    const cv::Mat mask =
        cv::imread((out / "masks" / (pose.name + ".png")).string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(mask.empty());
    const double fx = camera.params[0], fy = camera.params[1];
    const double cx = camera.params[2], cy = camera.params[3];
    const cv::Mat drawn =
        DrawMask(*hull_, camera.width, camera.height, [&](const Eigen::Vector3d& world) {
          const Eigen::Vector3d p = pose.r * world + pose.t;
          EXPECT_GT(p.z(), 0.0);
          return Eigen::Vector2d(fx * p.x() / p.z() + cx, fy * p.y() / p.z() + cy);
        });
    const double iou = Iou(drawn, mask != 0);
    iou_sum += iou;
    iou_min = std::min(iou_min, iou);
  }
  const double mean = iou_sum / poses.size();
  std::printf("colmap export: hull through the exported cameras vs masks: IoU mean %.4f min %.4f\n",
              mean, iou_min);
  EXPECT_GE(mean, 0.98);

  // COLMAP reads it.
  if (Run("QT_QPA_PLATFORM=offscreen colmap help").exit_code != 0) {
    GTEST_SKIP() << "colmap (Debian's colmap) cannot run here; ./run installs it";
  }
  const RunResult converted = Run("QT_QPA_PLATFORM=offscreen colmap model_converter --input_path " +
                                  (out / "sparse/0").string() + " --output_path " +
                                  (dir_ / "model.nvm").string() + " --output_type NVM");
  ASSERT_EQ(converted.exit_code, 0) << converted.out << converted.err;
  // NVM: "NVM_V3", a blank line, then the camera count and one line per camera.
  std::istringstream nvm(ReadAll(dir_ / "model.nvm"));
  std::string header;
  int count = 0;
  nvm >> header >> count;
  EXPECT_EQ(header, "NVM_V3");
  EXPECT_EQ(count, 12);
}

TEST_F(ExportTest, NerfstudioTransformsProjectTheHullOntoTheMasks) {
  ASSERT_NO_FATAL_FAILURE(Scan());
  const fs::path out = dir_ / "ns";
  const RunResult r =
      Revolve("export " + scan_.string() + " --format nerfstudio --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const nlohmann::json t = nlohmann::json::parse(ReadAll(out / "transforms.json"));
  const double fx = t["fl_x"], fy = t["fl_y"], cx = t["cx"], cy = t["cy"];
  const int w = t["w"], h = t["h"];
  EXPECT_EQ(t["camera_model"], "OPENCV");
  ASSERT_EQ(t["frames"].size(), 12u);
  double iou_sum = 0.0;
  for (const nlohmann::json& frame : t["frames"]) {
    const std::string file = frame["file_path"];
    SCOPED_TRACE(file);
    EXPECT_FALSE(cv::imread((out / file).string()).empty());
    const cv::Mat mask =
        cv::imread((out / frame["mask_path"].get<std::string>()).string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(mask.empty());
    Eigen::Matrix4d c2w;
    for (int i = 0; i < 4; ++i) {
      for (int j = 0; j < 4; ++j) c2w(i, j) = frame["transform_matrix"][i][j];
    }
    EXPECT_NEAR((c2w.topLeftCorner<3, 3>().determinant()), 1.0, 1e-9);
    EXPECT_EQ(c2w.row(3), Eigen::RowVector4d(0, 0, 0, 1));
    // The camera looks at the object (on the plate, around the axis) along its -z (OpenGL),
    // and its +y points up the table's axis (a level-ish camera).
    const Eigen::Vector3d centre = c2w.topRightCorner<3, 1>();
    const Eigen::Vector3d back = c2w.block<3, 1>(0, 2);
    EXPECT_GT(back.dot(centre - Eigen::Vector3d(0, 0, 40)), 0.9 * (centre.norm() - 40.0));
    EXPECT_GT(c2w(2, 1), 0.5);
    const Eigen::Matrix4d w2c = c2w.inverse();
    const cv::Mat drawn = DrawMask(*hull_, w, h, [&](const Eigen::Vector3d& world) {
      const Eigen::Vector3d p = (w2c * world.homogeneous()).head<3>();
      EXPECT_LT(p.z(), 0.0);  // in front: OpenGL cameras look down -z
      return Eigen::Vector2d(fx * p.x() / -p.z() + cx, fy * -p.y() / -p.z() + cy);
    });
    iou_sum += Iou(drawn, mask != 0);
  }
  const double mean = iou_sum / t["frames"].size();
  std::printf("nerfstudio export: hull through the exported cameras vs masks: IoU mean %.4f\n",
              mean);
  EXPECT_GE(mean, 0.98);
}

// COLMAP's own pipeline on the export: features inside the masks, matched, triangulated with
// the exported poses held fixed; the points lie on the hull.
TEST_F(ExportTest, ColmapTriangulatesPointsOnTheHull) {
  if (Run("QT_QPA_PLATFORM=offscreen colmap help").exit_code != 0) {
    GTEST_SKIP() << "colmap (Debian's colmap) cannot run here; ./run installs it";
  }
  ASSERT_NO_FATAL_FAILURE(Scan());
  const fs::path out = dir_ / "colmap";
  RunResult r = Revolve("export " + scan_.string() + " --format colmap --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const std::map<int, Camera> cameras = ReadCameras(out / "sparse/0/cameras.txt");
  ASSERT_EQ(cameras.size(), 1u);
  std::string params;
  for (double p : cameras.begin()->second.params) {
    params += (params.empty() ? "" : ",") + fmt::format("{:.17g}", p);
  }
  const std::string colmap = "QT_QPA_PLATFORM=offscreen colmap ";
  // One extraction thread: the database numbers the images in file-name order, as images.txt
  // does (several threads number them as they finish, and point_triangulator then refuses the
  // model).
  const std::string db = (dir_ / "colmap.db").string();
  r = Run(colmap + "feature_extractor --database_path " + db + " --image_path " +
          (out / "images").string() + " --ImageReader.mask_path " + (out / "masks").string() +
          " --ImageReader.camera_model PINHOLE --ImageReader.single_camera 1"
          " --ImageReader.camera_params " +
          params + " --SiftExtraction.use_gpu 0 --SiftExtraction.num_threads 1");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  r = Run(colmap + "exhaustive_matcher --database_path " + db +
          " --SiftMatching.use_gpu 0 --SiftMatching.num_threads 2");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const fs::path triangulated = dir_ / "triangulated";
  fs::create_directories(triangulated);
  r = Run(colmap + "point_triangulator --database_path " + db + " --image_path " +
          (out / "images").string() + " --input_path " + (out / "sparse/0").string() +
          " --output_path " + triangulated.string());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const fs::path text = dir_ / "triangulated_txt";
  fs::create_directories(text);
  r = Run(colmap + "model_converter --input_path " + triangulated.string() + " --output_path " +
          text.string() + " --output_type TXT");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;

  // The poses were held fixed: the triangulated model's images are the export's.
  int camera_id = 0;
  const std::vector<Pose> exported = ReadImages(out / "sparse/0/images.txt", &camera_id);
  std::map<std::string, Pose> fixed;
  const std::vector<std::string> lines = DataLines(text / "images.txt");
  for (std::size_t i = 0; i < lines.size(); i += 2) {  // the pose; the next line its 2D points
    std::istringstream in(lines[i]);
    int id = 0;
    double qw, qx, qy, qz, tx, ty, tz;
    std::string name;
    if (in >> id >> qw >> qx >> qy >> qz >> tx >> ty >> tz >> camera_id >> name) {
      fixed[name].r = RotationFromQuaternion(qw, qx, qy, qz);
      fixed[name].t = Eigen::Vector3d(tx, ty, tz);
    }
  }
  ASSERT_EQ(fixed.size(), exported.size());
  for (const Pose& p : exported) {
    EXPECT_LT((fixed[p.name].r - p.r).norm(), 1e-9) << p.name;
    EXPECT_LT((fixed[p.name].t - p.t).norm(), 1e-6) << p.name;
  }

  const revolve::capture::MeshGrid grid(hull_);
  std::vector<double> distances;
  for (const std::string& line : DataLines(text / "points3D.txt")) {
    std::istringstream in(line);
    long id = 0;
    Eigen::Vector3d x;
    if (in >> id >> x.x() >> x.y() >> x.z()) distances.push_back(grid.Distance(x));
  }
  ASSERT_GE(distances.size(), 60u) << "too few points triangulated";
  std::sort(distances.begin(), distances.end());
  const double median = distances[distances.size() / 2];
  const double p90 = distances[distances.size() * 9 / 10];
  std::printf(
      "colmap point_triangulator: %zu points, distance to the hull: median %.3f mm, "
      "90th percentile %.3f mm\n",
      distances.size(), median, p90);
  EXPECT_LT(median, 1.0);
}

TEST_F(ExportTest, MistakesAreNamed) {
  // A scan in thesis mode (the camera's geometry unknown): no pinhole cameras to export.
  std::string config = ScanConfig();
  config.replace(config.find("[camera.synthetic]\n"), 19,
                 "[camera.synthetic]\nknown_geometry = false\n");
  config.replace(config.find("resolution = 160"), 16, "resolution = 32");
  ASSERT_NO_FATAL_FAILURE(Scan(config));
  RunResult r =
      Revolve("export " + scan_.string() + " --format colmap --out " + (dir_ / "x").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("revolve calibrate"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(scan_.string()), std::string::npos) << r.err;

  r = Revolve("export " + scan_.string() + " --format ply --out " + (dir_ / "y").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--format ply"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "y"));

  r = Revolve("export " + (dir_ / "missing").string() + " --out " + (dir_ / "z").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find((dir_ / "missing").string()), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "z"));
}

}  // namespace
