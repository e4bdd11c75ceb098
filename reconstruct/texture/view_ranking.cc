#include <numeric>

#include "reconstruct/parallel.h"
#include "reconstruct/texture/texture_internal.h"

namespace revolve::reconstruct::texture_internal {
namespace {

constexpr std::size_t kNormalsPerTask = 8192;

// Per view k, the entries emit(i, slot) of the items i in [0, n) and their slots with
// view_of(i, slot) == k (-1: none; the slots of an item in increasing order, a -1 ending them),
// in item order: a counting sort, on all cores in fixed chunks of items (each chunk counts its
// entries per view, then writes them where the chunks before it end), so the same entries in
// the same order as one pass.
template <typename Entry, typename ViewOf, typename Emit>
PerView<Entry> SortByView(int nviews, std::size_t n, const ViewOf& view_of, const Emit& emit) {
  const std::size_t chunks = (n + kNormalsPerTask - 1) / kNormalsPerTask;
  std::vector<int> count(chunks * nviews, 0);  // chunk-major
  // fn(i, slot, view) for every candidate of the chunk's items, in order.
  const auto each = [&](std::size_t chunk, const auto& fn) {
    for (std::size_t i = chunk * kNormalsPerTask; i < std::min(n, (chunk + 1) * kNormalsPerTask);
         ++i) {
      for (int slot = 0; slot < kCandidates; ++slot) {
        const int k = view_of(i, slot);
        if (k < 0) break;
        fn(i, slot, k);
      }
    }
  };
  ParallelFor(0, chunks, [&](std::size_t chunk) {
    int* own = &count[chunk * nviews];
    each(chunk, [own](std::size_t, int, int k) { ++own[k]; });
  });
  PerView<Entry> out;
  out.start.assign(nviews + 1, 0);
  // count[chunk][k] becomes where chunk's entries of view k start.
  int at = 0;
  for (int k = 0; k < nviews; ++k) {
    out.start[k] = at;
    for (std::size_t chunk = 0; chunk < chunks; ++chunk) {
      const int c = count[chunk * nviews + k];
      count[chunk * nviews + k] = at;
      at += c;
    }
  }
  out.start[nviews] = at;
  out.entries.resize(at);
  ParallelFor(0, chunks, [&](std::size_t chunk) {
    int* fill = &count[chunk * nviews];
    each(chunk, [&](std::size_t i, int slot, int k) { out.entries[fill[k]++] = emit(i, slot); });
  });
  return out;
}

}  // namespace

ViewRanking::ViewRanking(const std::vector<ViewGeometry>& geometry,
                         const std::vector<cv::Mat>& images, const Surface& surface, float cos_min)
    : cos_min_(cos_min) {
  const int nviews = static_cast<int>(geometry.size());
  direction_.resize(nviews);
  margin_.assign(nviews, 0.0f);
  for (int k = 0; k < nviews; ++k) {
    const ViewGeometry& g = geometry[k];
    direction_[k] = g.ToCamera(surface.centre);
    if (!g.affine) {
      const float distance = (g.centre - surface.centre).norm();
      margin_[k] =
          distance > surface.radius ? std::min(1.0f, 1.05f * surface.radius / distance) : 2.0f;
    }
  }
  bins_.resize(std::size_t{6} * kBins * kBins);
  std::vector<int> used_views;  // those with an image, and their directions
  std::vector<float> used_x, used_y, used_z;
  for (int k = 0; k < nviews; ++k) {
    if (images[k].empty()) continue;
    used_views.push_back(k);
    used_x.push_back(direction_[k].x());
    used_y.push_back(direction_[k].y());
    used_z.push_back(direction_[k].z());
  }
  // Each bin apart: the rows of bins on all cores.
  ParallelFor(0, std::size_t{6} * kBins, [&](std::size_t row) {
    const int face = static_cast<int>(row) / kBins;
    const int bt = static_cast<int>(row) % kBins;
    std::vector<float> used_score(used_views.size());
    for (int bs = 0; bs < kBins; ++bs) {
      const float a = 2.0f * (bs + 0.5f) / kBins - 1.0f;
      const float b = 2.0f * (bt + 0.5f) / kBins - 1.0f;
      Eigen::Vector3f n;
      const float sign = face & 1 ? -1.0f : 1.0f;
      switch (face / 2) {
        case 0:
          n = Eigen::Vector3f(sign, a, b);
          break;
        case 1:
          n = Eigen::Vector3f(a, sign, b);
          break;
        default:
          n = Eigen::Vector3f(a, b, sign);
          break;
      }
      n.normalize();
      // The scores first (one loop the compiler vectorises; the products summed in the order
      // of Eigen's dot: x + (y + z)), then the best kCandidates, in a local copy.
      for (std::size_t j = 0; j < used_views.size(); ++j) {
        used_score[j] = n.x() * used_x[j] + (n.y() * used_y[j] + n.z() * used_z[j]);
      }
      Candidates c;
      for (std::size_t j = 0; j < used_views.size(); ++j) c.Insert(used_score[j], used_views[j]);
      bins_[(face * kBins + bt) * kBins + bs] = c;
    }
  });
}

int ViewRanking::BinOf(float x, float y, float z) {
  const float ax = std::abs(x), ay = std::abs(y), az = std::abs(z);
  int face;
  float a, b, m;
  if (ax >= ay && ax >= az) {
    face = x >= 0.0f ? 0 : 1, a = y, b = z, m = ax;
  } else if (ay >= az) {
    face = y >= 0.0f ? 2 : 3, a = x, b = z, m = ay;
  } else {
    face = z >= 0.0f ? 4 : 5, a = x, b = y, m = az;
  }
  const float inv = m > 0.0f ? 0.5f * kBins / m : 0.0f;
  const int bs = std::clamp(static_cast<int>((a + m) * inv), 0, kBins - 1);
  const int bt = std::clamp(static_cast<int>((b + m) * inv), 0, kBins - 1);
  return (face * kBins + bt) * kBins + bs;
}

Candidates ViewRanking::Rank(float x, float y, float z) const {
  Candidates c;
  if (x == 0.0f && y == 0.0f && z == 0.0f) return c;
  const Candidates& bin = bins_[BinOf(x, y, z)];
  for (int slot = 0; slot < kCandidates; ++slot) {
    const int k = bin.view[slot];
    if (k < 0) break;
    const Eigen::Vector3f& d = direction_[k];
    const float score = x * d.x() + y * d.y() + z * d.z();
    // Above -2 (cos_min - margin >= cos 85 deg - 2), so it takes a slot.
    if (score < cos_min_ - margin_[k]) continue;
    c.Insert(score, k);
  }
  return c;
}

std::vector<Candidates> ViewRanking::Rank(int count, const float* x, const float* y,
                                          const float* z) const {
  std::vector<Candidates> out(count);
  ParallelChunks(0, static_cast<std::size_t>(count), kNormalsPerTask,
                 [&](std::size_t lo, std::size_t hi) {
                   for (std::size_t i = lo; i < hi; ++i) out[i] = Rank(x[i], y[i], z[i]);
                 });
  return out;
}

PerView<std::int64_t> ViewRanking::FacesPerView(
    const std::vector<Candidates>& face_candidates) const {
  // (A candidate's slots are filled from the first: the first empty one ends them.)
  return SortByView<std::int64_t>(
      static_cast<int>(direction_.size()), face_candidates.size(),
      [&](std::size_t i, int slot) { return static_cast<int>(face_candidates[i].view[slot]); },
      [](std::size_t i, int slot) { return static_cast<std::int64_t>(i) * kCandidates + slot; });
}

PerView<int> ViewRanking::VerticesPerView(const std::vector<Eigen::Vector3f>& vertex_normal,
                                          bool wanted) const {
  const int nviews = static_cast<int>(direction_.size());
  const int nv = static_cast<int>(vertex_normal.size());
  PerView<int> out;
  std::vector<int>& vertex_start = out.start;
  vertex_start.assign(nviews + 1, 0);
  if (!wanted) return out;
  std::vector<std::array<std::int16_t, kCandidates>> ranked(nv);
  ParallelChunks(0, static_cast<std::size_t>(nv), kNormalsPerTask,
                 [&](std::size_t lo, std::size_t hi) {
                   for (std::size_t vi = lo; vi < hi; ++vi) {
                     const Eigen::Vector3f& n = vertex_normal[vi];
                     ranked[vi] = Rank(n.x(), n.y(), n.z()).view;
                   }
                 });
  return SortByView<int>(
      nviews, static_cast<std::size_t>(nv),
      [&](std::size_t vi, int slot) { return static_cast<int>(ranked[vi][slot]); },
      [](std::size_t vi, int) { return static_cast<int>(vi); });
}

}  // namespace revolve::reconstruct::texture_internal
