// The reprojection metrics' outline from face planes (reconstruct/metrics/outline_internal.h)
// gives what projecting and signing every face gives: the same silhouette pixels and the same
// IoUs, to the bit, on hull surfaces seen from around, above, below and close by, on a mesh with
// degenerate faces, and where a vertex lies behind the camera; and it decides most faces without
// projecting them.
#include <cmath>
#include <cstring>
#include <mutex>
#include <numeric>
#include <random>

#include <gtest/gtest.h>

#include "reconstruct/cameras/views.h"
#include "reconstruct/hull/visual_hull.h"
#include "reconstruct/metrics/metrics.h"
#include "reconstruct/metrics/outline_internal.h"
#include "reconstruct/metrics/reprojection.h"
#include "tests/reconstruct/sphere_scene.h"

namespace revolve::reconstruct {
namespace {

using outline_internal::OutlineCounts;
using outline_internal::OutlineIndex;

std::vector<testing::Sphere> Spheres() {
  return {{{0.0, 0.0, 40.0}, 35.0}, {{0.0, 0.0, 82.0}, 16.0}, {{28.0, 15.0, 55.0}, 14.0}};
}

// Hull surfaces of three spheres (concave where they meet): exact crossings at 64^3 and 96^3,
// midpoints at 40^3.
std::vector<Mesh> HullMeshes() {
  const Rig rig = testing::StationRig(450.0, 20.0, 50.0, 320, 240);
  std::vector<Mesh> meshes;
  for (const auto& [resolution, sub_voxel] :
       std::vector<std::pair<int, bool>>{{64, true}, {96, true}, {40, false}}) {
    VisualHull hull(*VoxelGrid::FromBox({-60, -60, 0}, {60, 60, 120}, resolution));
    for (int k = 0; k < 12; ++k) {
      EXPECT_TRUE(hull.Integrate(testing::SphereMask(rig, 30.0 * k, Spheres()),
                                 testing::ViewOf(rig, 30.0 * k)));
    }
    HullSurfaceOptions options;
    options.sub_voxel = sub_voxel;
    options.clip_below_z_mm = 0.0;
    meshes.push_back(hull.ExtractSurface(options));
  }
  return meshes;
}

// Views all around (pinhole, 20 degrees above), from high above, from below the plate, close
// by (the mesh filling much of a wide view), and orthographic (the thesis's, the mesh scaled to
// pixels by the caller's choice of size).
std::vector<View> Views() {
  std::vector<View> views;
  const Rig ring = testing::StationRig(450.0, 20.0, 50.0, 320, 240);
  for (int k = 0; k < 7; ++k) views.push_back(testing::ViewOf(ring, 13.0 + 51.0 * k));
  views.push_back(testing::ViewOf(testing::StationRig(400.0, 75.0, 50.0, 320, 240), 40.0));
  views.push_back(testing::ViewOf(testing::StationRig(400.0, -35.0, 50.0, 320, 240), 200.0));
  views.push_back(testing::ViewOf(testing::StationRig(110.0, 10.0, 50.0, 640, 480, 90.0), 75.0));
  for (const double angle : {0.0, 35.0, 90.0}) views.push_back(ThesisView(320, 240, angle));
  return views;
}

// The silhouette's pixels in a whole image of the view's size.
cv::Mat Whole(const BoxedSilhouette& silhouette, const View& view) {
  cv::Mat whole(view.height_px, view.width_px, CV_8UC1, cv::Scalar(0));
  if (!silhouette.box.empty()) silhouette.pixels.copyTo(whole(silhouette.box));
  return whole;
}

// SilhouetteFromOutline against SilhouetteFromEveryEdge in `view`: the same pixels (or both
// nullopt). Returns the counts.
OutlineCounts ExpectSameSilhouette(const Mesh& mesh, const View& view, const std::string& what) {
  const std::vector<outline_internal::SharedEdge> edges = outline_internal::SharedEdges(mesh);
  const OutlineIndex index(mesh);
  EXPECT_TRUE(index.closed()) << what;
  EXPECT_FALSE(edges.empty()) << what;
  OutlineCounts counts;
  const std::optional<BoxedSilhouette> every = SilhouetteFromEveryEdge(mesh, edges, view);
  const std::optional<BoxedSilhouette> planes = SilhouetteFromOutline(mesh, index, view, &counts);
  EXPECT_EQ(every.has_value(), planes.has_value()) << what;
  if (every && planes) {
    const cv::Mat a = Whole(*every, view);
    EXPECT_GT(cv::countNonZero(a), 0) << what;
    EXPECT_EQ(cv::countNonZero(a != Whole(*planes, view)), 0) << what;
    // The box is the outline's rectangle: within the every-vertex one.
    EXPECT_EQ(planes->box & every->box, planes->box) << what;
  }
  return counts;
}

// The written-out projection rounds as Eigen's expression does (what the metrics projected
// with before, and View::Project still does): every vertex of the hulls, in every view, and
// random points of every magnitude.
TEST(Outline, HomogeneousIsEigensToTheBit) {
  std::vector<Eigen::Vector3f> points;
  for (const Mesh& mesh : HullMeshes()) {
    points.insert(points.end(), mesh.vertices.begin(), mesh.vertices.end());
  }
  std::mt19937 random(11);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  for (int i = 0; i < 20000; ++i) {
    const float scale = std::pow(10.0f, static_cast<float>(i % 9) - 3.0f);
    points.emplace_back(scale * unit(random), scale * unit(random), scale * unit(random));
  }
  std::vector<View> views = Views();
  View skewed = views.front();
  skewed.pixel_from_object.row(2) += Eigen::RowVector4d(1e-3, -2e-3, 3e-3, 0.7);
  views.push_back(skewed);
  for (const View& view : views) {
    for (const Eigen::Vector3f& point : points) {
      const Eigen::Vector3d eigen = view.pixel_from_object.leftCols<3>() * point.cast<double>() +
                                    view.pixel_from_object.col(3);
      const Eigen::Vector3d written = outline_internal::Homogeneous(view, point);
      ASSERT_EQ(std::memcmp(eigen.data(), written.data(), sizeof(double) * 3), 0)
          << point.transpose() << " " << eigen.transpose() << " " << written.transpose();
    }
  }
}

// The index's face planes, altitudes and shared axes (computed on vectors, from rows of corners)
// are Eigen's expressions to the bit: on hull surfaces, random faces of every scale, and faces
// with repeated corners, in a line, or flat along an axis.
TEST(Outline, FacePlanesAreEigensToTheBit) {
  Mesh mesh;
  for (const Mesh& hull : HullMeshes()) {
    const auto base = static_cast<int>(mesh.vertices.size());
    mesh.vertices.insert(mesh.vertices.end(), hull.vertices.begin(), hull.vertices.end());
    for (const Eigen::Vector3i& f : hull.faces)
      mesh.faces.push_back(f + Eigen::Vector3i::Constant(base));
  }
  std::mt19937 random(5);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  for (int i = 0; i < 30000; ++i) {
    const float scale = std::pow(10.0f, static_cast<float>(i % 9) - 3.0f);
    const auto corner = [&] {
      return Eigen::Vector3f(scale * unit(random), scale * unit(random), scale * unit(random));
    };
    const Eigen::Vector3f a = corner();
    Eigen::Vector3f b = corner();
    Eigen::Vector3f c = corner();
    if (i % 7 == 1) b = a;                   // repeated corner
    if (i % 7 == 2) c = a + 2.0f * (b - a);  // in a line
    if (i % 7 == 3) b.z() = c.z() = a.z();   // flat along z
    if (i % 7 == 4) b = c = a;               // a point
    const auto first = static_cast<int>(mesh.vertices.size());
    mesh.vertices.insert(mesh.vertices.end(), {a, b, c});
    mesh.faces.emplace_back(first, first + 1, first + 2);
  }
  const OutlineIndex index(mesh);
  ASSERT_TRUE(index.finite());
  ASSERT_EQ(index.normal_x().size(), mesh.faces.size());
  for (std::size_t i = 0; i < mesh.faces.size(); ++i) {
    const Eigen::Vector3i& f = mesh.faces[i];
    std::uint8_t shared = 0;
    for (int axis = 0; axis < 3; ++axis) {
      const float x = mesh.vertices[f[0]][axis];
      if (mesh.vertices[f[1]][axis] == x && mesh.vertices[f[2]][axis] == x) {
        shared |= static_cast<std::uint8_t>(1u << axis);
      }
    }
    const Eigen::Vector3d a = mesh.vertices[f[0]].cast<double>();
    const Eigen::Vector3d b = mesh.vertices[f[1]].cast<double>();
    const Eigen::Vector3d c = mesh.vertices[f[2]].cast<double>();
    const Eigen::Vector3d n = (b - a).cross(c - a);
    const double n_norm = n.norm();
    const double longest =
        std::sqrt(std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()}));
    float expected[5] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    if (n_norm > 0.0 && longest > 0.0) {
      const Eigen::Vector3d u = n / n_norm;
      expected[0] = static_cast<float>(u.x());
      expected[1] = static_cast<float>(u.y());
      expected[2] = static_cast<float>(u.z());
      expected[3] = static_cast<float>(u.dot(a));
      expected[4] = static_cast<float>(n_norm / longest);
    }
    const float got[5] = {index.normal_x()[i], index.normal_y()[i], index.normal_z()[i],
                          index.offset()[i], index.height()[i]};
    ASSERT_EQ(std::memcmp(expected, got, sizeof(got)), 0) << "face " << i;
    ASSERT_EQ(index.shared_axes()[i], shared) << "face " << i;
  }
}

TEST(Outline, PlanesGiveTheSilhouetteOfEveryEdgeOnHulls) {
  const std::vector<View> views = Views();
  const std::vector<Mesh> meshes = HullMeshes();
  for (std::size_t m = 0; m < meshes.size(); ++m) {
    ASSERT_GT(meshes[m].faces.size(), 1000u);
    int undecided = 0;
    for (std::size_t v = 0; v < views.size(); ++v) {
      Mesh mesh = meshes[m];
      if (views[v].IsAffine()) {  // the thesis's pixels: 2 px a millimetre
        for (Eigen::Vector3f& p : mesh.vertices) p *= 2.0f;
      }
      const std::string what = "mesh " + std::to_string(m) + " view " + std::to_string(v);
      const OutlineCounts counts = ExpectSameSilhouette(mesh, views[v], what);
      EXPECT_FALSE(counts.every_face) << what;
      // Most faces are decided by their planes (in the ring's views), the rest (near grazing)
      // exactly; midpoint surfaces have faces exactly along the thesis's axis-aligned views.
      EXPECT_GT(counts.decided, (v < 7 ? 0.8 : 0.5) * counts.faces) << what;
      undecided += counts.faces - counts.decided;
      EXPECT_GT(counts.outline_edges, 0) << what;
      // And the pixels are those of drawing every face.
      const std::optional<BoxedSilhouette> planes =
          SilhouetteFromOutline(mesh, OutlineIndex(mesh), views[v]);
      ASSERT_TRUE(planes);
      EXPECT_EQ(cv::countNonZero(Whole(*planes, views[v]) != RenderSilhouette(mesh, views[v])), 0)
          << what;
    }
    EXPECT_GT(undecided, 0) << m;  // the exact path was taken
  }
}

// A face replaced by three around a new vertex placed on a corner or on an edge's midpoint: two
// of them have no area (coincident or collinear corners); the mesh stays closed and oriented.
Mesh WithDegenerateFaces(const Mesh& mesh) {
  Mesh out = mesh;
  out.faces.clear();
  for (std::size_t i = 0; i < mesh.faces.size(); ++i) {
    const Eigen::Vector3i& f = mesh.faces[i];
    if (i % 7 != 0) {
      out.faces.push_back(f);
      continue;
    }
    const int m = static_cast<int>(out.vertices.size());
    out.vertices.push_back(i % 2 == 0 ? mesh.vertices[f[0]]
                                      : 0.5f * (mesh.vertices[f[0]] + mesh.vertices[f[1]]));
    out.faces.emplace_back(f[0], f[1], m);
    out.faces.emplace_back(f[1], f[2], m);
    out.faces.emplace_back(f[2], f[0], m);
  }
  return out;
}

TEST(Outline, PlanesGiveTheSilhouetteOfEveryEdgeWithDegenerateFaces) {
  const Mesh mesh = WithDegenerateFaces(HullMeshes().front());
  const MeshStats stats = ComputeStats(mesh);
  ASSERT_TRUE(stats.closed && stats.oriented);
  const std::vector<View> views = Views();
  for (std::size_t v = 0; v < views.size(); ++v) {
    if (views[v].IsAffine()) continue;
    const OutlineCounts counts = ExpectSameSilhouette(mesh, views[v], "view " + std::to_string(v));
    // At least the degenerate faces (a seventh of the originals, two each) are projected.
    EXPECT_LT(counts.decided, counts.faces - counts.faces / 12) << v;
  }
}

// Cameras within the sphere around a long, flat slab: one with every vertex in front (the
// sphere does not decide it), one with vertices behind it (both nullopt).
TEST(Outline, CamerasNearOrInsideTheMeshSphere) {
  VisualHull hull(*VoxelGrid::FromBox({-60, -60, 0}, {60, 60, 8}, 48));
  const Rig rig = testing::StationRig(450.0, 70.0, 4.0, 320, 240);
  for (int k = 0; k < 8; ++k) {
    std::vector<testing::Sphere> spheres;
    for (int i = -3; i <= 3; ++i) spheres.push_back({{12.0 * i, 0.0, 4.0}, 9.0});
    ASSERT_TRUE(hull.Integrate(testing::SphereMask(rig, 45.0 * k, spheres),
                               testing::ViewOf(rig, 45.0 * k)));
  }
  HullSurfaceOptions options;
  options.clip_below_z_mm = 0.0;
  const Mesh slab = hull.ExtractSurface(options);
  ASSERT_GT(slab.faces.size(), 100u);
  // 30 mm from the axis, level, across the slab (in front of every vertex; the sphere around
  // them, radius ~46 mm, crosses the camera plane) and along it (vertices behind the camera):
  // decided by projecting every vertex, as SilhouetteFromEveryEdge does.
  const Rig near = testing::StationRig(30.0, 0.0, 4.0, 320, 240, 120.0);
  int seen = 0;
  int behind = 0;
  for (const double angle : {0.0, 90.0}) {
    const View view = testing::ViewOf(near, angle);
    const OutlineCounts counts = ExpectSameSilhouette(slab, view, std::to_string(angle));
    EXPECT_TRUE(counts.every_face) << angle;
    const bool drawn = SilhouetteFromOutline(slab, OutlineIndex(slab), view).has_value();
    seen += drawn;
    behind += !drawn;
  }
  EXPECT_EQ(seen, 1);
  EXPECT_EQ(behind, 1);
}

// All views at once give what each view alone gives: the same box and pixels, or both nullopt,
// each view told once: 41 pinhole and orthographic views (two batches, the first full) and two
// that are not batched (a camera inside the mesh: nullopt; one whose sphere test fails but sees
// every vertex), on hulls with exact crossings and with midpoints.
TEST(Outline, AllViewsAtOnceGiveEachViewsSilhouette) {
  const Rig ring = testing::StationRig(450.0, 20.0, 50.0, 320, 240);
  std::vector<View> views;
  for (int k = 0; k < 36; ++k) views.push_back(testing::ViewOf(ring, 10.0 * k));
  for (const double angle : {0.0, 35.0, 90.0, 180.0}) views.push_back(ThesisView(320, 240, angle));
  views.push_back(testing::ViewOf(testing::StationRig(400.0, 75.0, 50.0, 320, 240), 40.0));
  views.push_back(testing::ViewOf(testing::StationRig(20.0, 0.0, 40.0, 320, 240, 120.0), 0.0));
  views.push_back(testing::ViewOf(testing::StationRig(40.0, 0.0, 40.0, 320, 240, 120.0), 30.0));
  for (const Mesh& mesh : HullMeshes()) {
    const OutlineIndex index(mesh);
    ASSERT_TRUE(index.closed());
    std::vector<std::optional<BoxedSilhouette>> together(views.size());
    std::vector<int> told(views.size(), 0);
    std::mutex mutex;
    outline_internal::SilhouettesFromOutline(
        mesh, index, views, [&](std::size_t i, std::optional<BoxedSilhouette> silhouette) {
          const std::lock_guard<std::mutex> lock(mutex);
          ++told[i];
          together[i] = std::move(silhouette);
        });
    int drawn = 0;
    int every_face = 0;
    for (std::size_t v = 0; v < views.size(); ++v) {
      OutlineCounts counts;
      const std::optional<BoxedSilhouette> alone =
          SilhouetteFromOutline(mesh, index, views[v], &counts);
      every_face += counts.every_face;
      EXPECT_EQ(told[v], 1) << v;
      ASSERT_EQ(alone.has_value(), together[v].has_value()) << v;
      if (!alone) continue;
      ++drawn;
      EXPECT_EQ(alone->box, together[v]->box) << v;
      ASSERT_EQ(alone->pixels.size(), together[v]->pixels.size()) << v;
      EXPECT_EQ(cv::countNonZero(alone->pixels != together[v]->pixels), 0) << v;
      EXPECT_GT(cv::countNonZero(alone->pixels), 0) << v;
    }
    EXPECT_EQ(drawn, static_cast<int>(views.size()) - 1);  // the camera inside the mesh
    EXPECT_EQ(every_face, 2);
  }
}

// The thesis's views at 10 degree steps and two more (38: two batches of the outline search),
// 320x240: every vertex on the row (height - 1) - z in each.
std::vector<View> ThesisViewsAround() {
  std::vector<View> views;
  views.reserve(38);
  for (int k = 0; k < 36; ++k) views.push_back(ThesisView(320, 240, 10.0 * k));
  for (const double angle : {35.0, -90.0}) views.push_back(ThesisView(320, 240, angle));
  return views;
}

// SilhouettesFromSlices on the thesis's views: that it slices `mesh`, and that every view's
// pixels are its own alone (SilhouetteFromOutline), the box within that one's.
void ExpectEachViewsPixels(const Mesh& mesh, const std::string& what) {
  const std::vector<View> views = ThesisViewsAround();
  const OutlineIndex index(mesh);
  ASSERT_TRUE(index.closed()) << what;
  std::vector<std::size_t> all(views.size());
  std::iota(all.begin(), all.end(), std::size_t{0});
  std::vector<int> told(views.size(), 0);
  std::vector<std::optional<BoxedSilhouette>> together(views.size());
  std::mutex mutex;
  const auto sink = [&](std::size_t i, std::optional<BoxedSilhouette> silhouette) {
    const std::lock_guard<std::mutex> lock(mutex);
    ++told[i];
    together[i] = std::move(silhouette);
  };
  ASSERT_TRUE(outline_internal::SilhouettesFromSlices(mesh, index, views, all, sink)) << what;
  for (std::size_t v = 0; v < views.size(); ++v) {
    EXPECT_EQ(told[v], 1) << what << " view " << v;
    const std::optional<BoxedSilhouette> alone = SilhouetteFromOutline(mesh, index, views[v]);
    ASSERT_TRUE(alone.has_value()) << what << " view " << v;
    ASSERT_TRUE(together[v].has_value()) << what << " view " << v;
    const cv::Mat a = Whole(*alone, views[v]);
    EXPECT_GT(cv::countNonZero(a), 0) << what << " view " << v;
    EXPECT_EQ(cv::countNonZero(a != Whole(*together[v], views[v])), 0) << what << " view " << v;
    EXPECT_EQ(together[v]->box & alone->box, together[v]->box) << what << " view " << v;
  }
}

// A box's 12 faces, outward.
Mesh BoxMesh(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi) {
  Mesh mesh;
  for (int i = 0; i < 8; ++i) {
    mesh.vertices.emplace_back((i & 1) != 0 ? hi.x() : lo.x(), (i & 2) != 0 ? hi.y() : lo.y(),
                               (i & 4) != 0 ? hi.z() : lo.z());
  }
  mesh.faces = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  return mesh;
}

// The thesis's views share their rows: their silhouettes come from the mesh's slices, each
// view's own pixels, on hulls with exact crossings and with midpoints (many corners exactly on a
// row, bottoms among them), on two solids side by side (two loops on a row, a gap between them),
// on a box whose corners lie between rows, and on one whose flat bottom lies on a row (the fill
// sets the pixels its outline runs through there, which the slices below the row do not hold:
// those views are searched for their outlines).
TEST(Outline, ViewsSharingTheirRowsAreSlicedWithEachViewsPixels) {
  int hull = 0;
  for (const Mesh& mesh : HullMeshes()) {
    ExpectEachViewsPixels(mesh, "hull " + std::to_string(hull++));
  }
  Mesh two = BoxMesh({-60, -10, 20.25f}, {-20, 10, 80.25f});
  const Mesh right = BoxMesh({20, -15, 30.75f}, {50, 15, 90.75f});
  for (const Eigen::Vector3i& f : right.faces) {
    two.faces.emplace_back(f + Eigen::Vector3i::Constant(8));
  }
  two.vertices.insert(two.vertices.end(), right.vertices.begin(), right.vertices.end());
  ExpectEachViewsPixels(two, "two boxes");
  ExpectEachViewsPixels(BoxMesh({-30, -20, 20.5f}, {30, 20, 100.5f}), "box between rows");
  ExpectEachViewsPixels(BoxMesh({-30, -20, 20}, {30, 20, 100}), "box on rows");
  // A pinhole view among them: not sliced, nothing told.
  const Mesh box = BoxMesh({-30, -20, 20.5f}, {30, 20, 100.5f});
  std::vector<View> views = ThesisViewsAround();
  views.push_back(testing::ViewOf(testing::StationRig(450.0, 20.0, 50.0, 320, 240), 0.0));
  std::vector<std::size_t> all(views.size());
  std::iota(all.begin(), all.end(), std::size_t{0});
  int told = 0;
  EXPECT_FALSE(outline_internal::SilhouettesFromSlices(
      box, OutlineIndex(box), views, all,
      [&](std::size_t, const std::optional<BoxedSilhouette>&) { ++told; }));
  EXPECT_EQ(told, 0);
}

// A tetrahedron's four faces, outward, on vertices first .. first + 3.
void AddTetrahedron(Mesh* mesh, const Eigen::Vector3f& corner) {
  const int first = static_cast<int>(mesh->vertices.size());
  for (const Eigen::Vector3f& offset : {Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(10, 0, 0),
                                        Eigen::Vector3f(0, 10, 0), Eigen::Vector3f(0, 0, 10)}) {
    mesh->vertices.push_back(corner + offset);
  }
  for (const Eigen::Vector3i& f : {Eigen::Vector3i(0, 2, 1), Eigen::Vector3i(0, 1, 3),
                                   Eigen::Vector3i(0, 3, 2), Eigen::Vector3i(1, 2, 3)}) {
    mesh->faces.push_back(f + Eigen::Vector3i::Constant(first));
  }
}

// The outline index (what SilhouetteReprojection reports as closed_and_oriented, and what
// `reconstruct --images` then takes instead of checking the edges again) finds a mesh closed and
// oriented exactly when ComputeStats does: on flawless meshes, a face turned over, one removed,
// one doubled, a face with a repeated corner, and two solids sharing an edge (each direction run
// twice).
// Each face's neighbour across corner e -> e + 1 is the face that runs that edge backwards.
TEST(Outline, NeighboursRunEachEdgeBackwards) {
  for (const Mesh& mesh : HullMeshes()) {
    const std::vector<Eigen::Vector3i> neighbours = outline_internal::FaceNeighbours(mesh);
    ASSERT_EQ(neighbours.size(), mesh.faces.size());
    for (std::size_t i = 0; i < mesh.faces.size(); ++i) {
      for (int e = 0; e < 3; ++e) {
        const int a = mesh.faces[i][e];
        const int b = mesh.faces[i][(e + 1) % 3];
        const Eigen::Vector3i& other = mesh.faces[static_cast<std::size_t>(neighbours[i][e])];
        bool runs_back = false;
        for (int k = 0; k < 3; ++k) runs_back |= other[k] == b && other[(k + 1) % 3] == a;
        ASSERT_TRUE(runs_back) << "face " << i << " corner " << e;
      }
    }
  }
}

TEST(Outline, IndexFindsClosedAndOrientedAsComputeStatsDoes) {
  Mesh tetrahedron;
  AddTetrahedron(&tetrahedron, Eigen::Vector3f(0, 0, 30));
  std::vector<std::pair<std::string, Mesh>> meshes = {{"tetrahedron", tetrahedron},
                                                      {"hull", HullMeshes().back()}};
  Mesh two = tetrahedron;
  AddTetrahedron(&two, Eigen::Vector3f(40, 0, 30));
  meshes.emplace_back("two apart", two);
  for (const auto& [name, base] : std::vector<std::pair<std::string, Mesh>>(meshes)) {
    Mesh turned = base;
    std::swap(turned.faces[1][1], turned.faces[1][2]);
    meshes.emplace_back(name + " turned", turned);
    Mesh open = base;
    open.faces.pop_back();
    meshes.emplace_back(name + " open", open);
    Mesh doubled = base;
    doubled.faces.push_back(doubled.faces[0]);
    meshes.emplace_back(name + " doubled", doubled);
    Mesh repeated = base;
    repeated.faces.emplace_back(0, 0, 1);
    repeated.faces.emplace_back(0, 1, 0);
    meshes.emplace_back(name + " repeated corner", repeated);
  }
  // The second tetrahedron's edge 4-5 laid on the first's 0-1 (the same two vertices).
  Mesh sharing = tetrahedron;
  AddTetrahedron(&sharing, Eigen::Vector3f(0, 0, 30));
  for (std::size_t f = 4; f < 8; ++f) {
    for (int k = 0; k < 3; ++k) {
      if (sharing.faces[f][k] == 4) sharing.faces[f][k] = 0;
      if (sharing.faces[f][k] == 5) sharing.faces[f][k] = 1;
    }
  }
  meshes.emplace_back("sharing an edge", sharing);
  const View view = testing::ViewOf(testing::StationRig(450.0, 20.0, 50.0, 320, 240), 30.0);
  const cv::Mat mask = cv::Mat::zeros(view.height_px, view.width_px, CV_8UC1);
  int closed_count = 0;
  for (const auto& [name, mesh] : meshes) {
    const MeshStats stats = ComputeStats(mesh);
    const bool expected = stats.closed && stats.oriented;
    closed_count += expected;
    EXPECT_EQ(OutlineIndex(mesh).closed(), expected) << name;
    EXPECT_EQ(SilhouetteReprojection(mesh, {view}, {mask}).closed_and_oriented, expected) << name;
    EXPECT_EQ(outline_internal::SilhouetteReprojectionBy(
                  mesh, {view}, {mask}, {}, outline_internal::OutlineSearch::kEveryEdge)
                  .closed_and_oriented,
              expected)
        << name;
    // ComputeStats is its two halves.
    MeshStats halves = ComputeMeasures(mesh);
    EXPECT_FALSE(halves.closed || halves.oriented) << name;
    CheckEdges(mesh, &halves);
    EXPECT_EQ(halves.closed, stats.closed) << name;
    EXPECT_EQ(halves.oriented, stats.oriented) << name;
    EXPECT_EQ(halves.volume_mm3, stats.volume_mm3) << name;
    EXPECT_EQ(halves.area_mm2, stats.area_mm2) << name;
  }
  EXPECT_EQ(closed_count, 3);  // the three flawless meshes
}

// SilhouetteReprojection's IoUs, to the bit, from the planes and from every face, against masks
// that differ from the silhouettes (the analytic spheres, shifted 2 px).
TEST(Outline, ReprojectionIoUsEqualEveryEdgesToTheBit) {
  const std::vector<View> views = Views();
  const Mesh mesh = HullMeshes()[1];
  std::vector<cv::Mat> masks;
  for (const View& view : views) {
    cv::Mat mask = RenderSilhouette(mesh, view);
    cv::Mat shifted = cv::Mat::zeros(mask.size(), CV_8UC1);
    mask(cv::Rect(0, 0, mask.cols - 2, mask.rows))
        .copyTo(shifted(cv::Rect(2, 0, mask.cols - 2, mask.rows)));
    masks.push_back(shifted);
  }
  const ReprojectionStats every = outline_internal::SilhouetteReprojectionBy(
      mesh, views, masks, {}, outline_internal::OutlineSearch::kEveryEdge);
  const ReprojectionStats planes = SilhouetteReprojection(mesh, views, masks);
  ASSERT_EQ(every.iou.size(), views.size());
  for (std::size_t i = 0; i < views.size(); ++i) {
    EXPECT_EQ(planes.iou[i], every.iou[i]) << i;
    EXPECT_LT(planes.iou[i], 1.0) << i;
    EXPECT_GT(planes.iou[i], 0.5) << i;
  }
  EXPECT_EQ(planes.mean, every.mean);
  EXPECT_EQ(planes.worst_view, every.worst_view);
}

}  // namespace
}  // namespace revolve::reconstruct
