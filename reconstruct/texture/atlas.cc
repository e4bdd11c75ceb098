#include <limits>
#include <numeric>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include <tbb/enumerable_thread_specific.h>

#include "reconstruct/parallel.h"
#include "reconstruct/texture/texture_internal.h"
#include "reconstruct/union_find.h"

namespace revolve::reconstruct::texture_internal {
namespace {

constexpr std::size_t kFacesPerTask = 8192;
constexpr std::size_t kFacesPerChunk = 32768;  // GroupCharts' union-find

// Shelf packing of `sizes` (w, h) into a strip `width` wide; returns the height used, or -1
// when a rectangle is wider than the strip.
int PackShelves(const std::vector<Rect>& sizes, int width, std::vector<Rect>* placed) {
  std::vector<int> order(sizes.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return sizes[a].h > sizes[b].h; });
  placed->assign(sizes.size(), Rect{});
  int x = 0, y = 0, shelf = 0;
  for (int i : order) {
    const Rect& s = sizes[i];
    if (s.w > width) return -1;
    if (x + s.w > width) {
      y += shelf;
      x = 0;
      shelf = 0;
    }
    (*placed)[i] = Rect{x, y, s.w, s.h};
    x += s.w;
    shelf = std::max(shelf, s.h);
  }
  return y + shelf;
}

}  // namespace

namespace {

// The label ICM gives face i from the labels of its neighbours (`label`): the visible candidate
// maximising its cosine plus kNeighbourBonus per edge-neighbour with the same view; `keep` when
// none is visible.
inline int IcmLabel(const std::vector<float>& face_cos, const Candidates& candidates,
                    const std::array<int, 3>& around, const std::vector<int>& label, std::size_t i,
                    int keep) {
  int out = keep;
  float best = -std::numeric_limits<float>::infinity();
  for (int s = 0; s < kCandidates; ++s) {
    const float c = face_cos[i * kCandidates + s];
    if (c <= -2.0f) continue;
    const int view = candidates.view[s];
    float score = c;
    for (int nb : around) {
      if (nb >= 0 && label[nb] == view) score += kNeighbourBonus;
    }
    if (score > best) {
      best = score;
      out = view;
    }
  }
  return out;
}

}  // namespace

std::vector<int> LabelFaces(const std::vector<float>& face_cos,
                            const std::vector<Candidates>& face_candidates,
                            const std::vector<std::array<int, 3>>& neighbours) {
  const int nf = static_cast<int>(face_candidates.size());
  // The best visible candidate.
  std::vector<int> label(nf, -1);
  ParallelChunks(0, nf, kFacesPerTask, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t i = lo; i < hi; ++i) {
      float best = -2.0f;
      for (int s = 0; s < kCandidates; ++s) {
        const float c = face_cos[i * kCandidates + s];
        if (c > best) {
          best = c;
          label[i] = face_candidates[i].view[s];
        }
      }
    }
  });
  // Iterated conditional modes: each face takes the visible candidate maximising its cosine plus
  // kNeighbourBonus per edge-neighbour with the same view, so the small islands and ragged
  // borders that nearly equal views leave behind merge into their surroundings. Each pass reads
  // only the labels of the one before. A face's new label depends on its neighbours' labels
  // only (a face without a visible candidate keeps its -1), so after the first pass (every face,
  // on all cores) a pass need only look again at the faces next to one the pass before changed:
  // the others would choose as they did.
  if (kSmoothingPasses == 0) return label;
  std::vector<int> next(nf);
  const std::size_t chunks = (static_cast<std::size_t>(nf) + kFacesPerTask - 1) / kFacesPerTask;
  std::vector<std::vector<int>> changed_in(chunks);  // per chunk, in face order
  ParallelFor(0, chunks, [&](std::size_t chunk) {
    const std::size_t hi = std::min<std::size_t>(nf, (chunk + 1) * kFacesPerTask);
    for (std::size_t i = chunk * kFacesPerTask; i < hi; ++i) {
      next[i] = IcmLabel(face_cos, face_candidates[i], neighbours[i], label, i, label[i]);
      if (next[i] != label[i]) changed_in[chunk].push_back(static_cast<int>(i));
    }
  });
  label.swap(next);
  std::vector<int> changed;
  for (const std::vector<int>& part : changed_in)
    changed.insert(changed.end(), part.begin(), part.end());
  // Later passes: the faces next to a change (each once), their new labels from the labels of
  // the pass before, then applied.
  std::vector<std::uint8_t> listed(nf, 0);
  std::vector<int> dirty;
  std::vector<int> relabel;
  for (int pass = 1; pass < kSmoothingPasses && !changed.empty(); ++pass) {
    dirty.clear();
    for (const int f : changed) {
      for (const int nb : neighbours[f]) {
        if (nb >= 0 && !listed[nb]) {
          listed[nb] = 1;
          dirty.push_back(nb);
        }
      }
    }
    relabel.resize(dirty.size());
    ParallelChunks(0, dirty.size(), kFacesPerTask / 4, [&](std::size_t lo, std::size_t hi) {
      for (std::size_t d = lo; d < hi; ++d) {
        const auto i = static_cast<std::size_t>(dirty[d]);
        relabel[d] = IcmLabel(face_cos, face_candidates[i], neighbours[i], label, i, label[i]);
      }
    });
    changed.clear();
    for (std::size_t d = 0; d < dirty.size(); ++d) {
      listed[dirty[d]] = 0;
      if (relabel[d] != label[dirty[d]]) changed.push_back(dirty[d]);
    }
    for (std::size_t d = 0; d < dirty.size(); ++d) label[dirty[d]] = relabel[d];
  }
  return label;
}

Charts GroupCharts(const std::vector<int>& label,
                   const std::vector<std::array<int, 3>>& neighbours) {
  const int nf = static_cast<int>(label.size());
  Charts out;
  // The union-find in fixed chunks of faces on all cores: a chunk joins the pairs of its own
  // faces (its sets stay inside it, so the chunks touch apart), then the pairs across chunks are
  // joined in order on one thread, and each face's set read off (without writing) on all cores.
  // The sets do not depend on the order of the joins; each is named by its smallest face.
  UnionFind sets(nf);
  const std::size_t chunks = (static_cast<std::size_t>(nf) + kFacesPerChunk - 1) / kFacesPerChunk;
  std::vector<std::vector<std::pair<int, int>>> across(chunks);
  ParallelFor(0, chunks, [&](std::size_t chunk) {
    const int lo = static_cast<int>(chunk * kFacesPerChunk);
    const int hi = std::min(nf, lo + static_cast<int>(kFacesPerChunk));
    for (int i = lo; i < hi; ++i) {
      if (label[i] < 0) continue;
      for (int nb : neighbours[i]) {
        if (nb < 0 || label[nb] != label[i]) continue;
        // A pair of faces each other's neighbours once, from the later face.
        const std::array<int, 3>& back = neighbours[nb];
        if (nb > i && (back[0] == i || back[1] == i || back[2] == i)) continue;
        if (nb >= lo && nb < hi) {
          sets.Unite(i, nb);
        } else {
          across[chunk].emplace_back(i, nb);
        }
      }
    }
  });
  for (const auto& pairs : across) {
    for (const auto& [a, b] : pairs) sets.Unite(a, b);
  }
  std::vector<int> root(nf);
  ParallelChunks(0, nf, kFacesPerChunk, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t i = lo; i < hi; ++i) {
      int r = static_cast<int>(i);
      while (sets.parent[r] != r) r = sets.parent[r];
      root[i] = r;
    }
  });
  std::vector<int> chart_of(nf, -1);
  for (int i = 0; i < nf; ++i) {
    if (label[i] < 0) {
      ++out.unseen_faces;
      continue;
    }
    const int root_i = root[i];
    if (chart_of[root_i] < 0) {
      chart_of[root_i] = static_cast<int>(out.view.size());
      out.view.push_back(label[i]);
    }
    chart_of[i] = chart_of[root_i];
  }
  const int charts = static_cast<int>(out.view.size());
  out.count = charts;
  // Faces grouped by chart (counting sort); the unseen faces last.
  std::vector<int>& chart_start = out.start;
  chart_start.assign(charts + 2, 0);
  for (int i = 0; i < nf; ++i) ++chart_start[(chart_of[i] < 0 ? charts : chart_of[i]) + 1];
  std::partial_sum(chart_start.begin(), chart_start.end(), chart_start.begin());
  out.faces.resize(nf);
  std::vector<int> fill(chart_start.begin(), chart_start.end() - 1);
  for (int i = 0; i < nf; ++i) out.faces[fill[chart_of[i] < 0 ? charts : chart_of[i]]++] = i;
  return out;
}

ChartUvs ProjectCharts(const Mesh& mesh, const Charts& charts,
                       const std::vector<ViewGeometry>& geometry) {
  const int nv = static_cast<int>(mesh.vertices.size());
  ChartUvs out;
  out.source.resize(charts.count);
  out.uv_faces.resize(mesh.faces.size());
  // The charts on all cores. First each chart counts its vertices, then each projects its own
  // into its place in that order (the same arrays on any number of cores). A thread marks the
  // vertices its chart has reached with the chart's number (and, projecting, its uv's index).
  struct Marks {
    std::vector<int> chart, uv;
  };
  tbb::enumerable_thread_specific<Marks> marks([nv] {
    return Marks{std::vector<int>(nv, -1), std::vector<int>(nv)};
  });
  std::vector<int>& start = out.start;
  start.assign(charts.count + 1, 0);
  ParallelFor(0, charts.count, [&](std::size_t c) {
    std::vector<int>& stamp = marks.local().chart;
    int count = 0;
    for (int k = charts.start[c]; k < charts.start[c + 1]; ++k) {
      for (int corner = 0; corner < 3; ++corner) {
        const int vi = mesh.faces[charts.faces[k]][corner];
        if (stamp[vi] != static_cast<int>(c)) {
          stamp[vi] = static_cast<int>(c);
          ++count;
        }
      }
    }
    start[c + 1] = count;
  });
  std::partial_sum(start.begin(), start.end(), start.begin());
  out.u.resize(start.back());
  out.v.resize(start.back());
  out.in_front.resize(start.back());
  ParallelFor(0, charts.count, [&](std::size_t c) {
    Marks& local = marks.local();
    // The second pass marks with -2 - c: never a mark of the first.
    const int mark = -2 - static_cast<int>(c);
    const ViewGeometry& g = geometry[charts.view[c]];
    // The rectangle of the vertices that project (each once: the same minimum and maximum).
    float u0 = std::numeric_limits<float>::infinity(), v0 = u0, u1 = -u0, v1 = -u0;
    int next = start[c];
    for (int k = charts.start[c]; k < charts.start[c + 1]; ++k) {
      const int fi = charts.faces[k];
      for (int corner = 0; corner < 3; ++corner) {
        const int vi = mesh.faces[fi][corner];
        if (local.chart[vi] != mark) {
          local.chart[vi] = mark;
          float u = 0.0f, v = 0.0f;
          const bool in_front = g.Project(mesh.vertices[vi], &u, &v);
          out.u[next] = u;
          out.v[next] = v;
          out.in_front[next] = in_front ? 1 : 0;
          if (in_front) {
            u0 = std::min(u0, u);
            u1 = std::max(u1, u);
            v0 = std::min(v0, v);
            v1 = std::max(v1, v);
          }
          local.uv[vi] = next++;
        }
        out.uv_faces[fi][corner] = local.uv[vi];
      }
    }
    Rect r;
    r.x = std::clamp(static_cast<int>(std::floor(u0)) - kChartMarginPx, 0, g.width - 1);
    r.y = std::clamp(static_cast<int>(std::floor(v0)) - kChartMarginPx, 0, g.height - 1);
    const int x1 = std::clamp(static_cast<int>(std::ceil(u1)) + kChartMarginPx, r.x, g.width - 1);
    const int y1 = std::clamp(static_cast<int>(std::ceil(v1)) + kChartMarginPx, r.y, g.height - 1);
    r.w = x1 - r.x + 1;
    r.h = y1 - r.y + 1;
    out.source[c] = r;
  });
  return out;
}

Expected<Packing> PackCharts(const std::vector<Rect>& source, int max_side) {
  const int charts = static_cast<int>(source.size());
  Packing out;
  std::vector<Rect> sizes(charts + 1);  // the unseen patch is rectangle `charts`
  double scale = 1.0;
  for (int attempt = 0; attempt < 40 && out.width == 0; ++attempt) {
    if (attempt > 0) scale *= 0.85;
    int widest = kUnseenPatch;
    for (int c = 0; c < charts; ++c) {
      sizes[c].w = std::max(1, static_cast<int>(std::ceil(source[c].w * scale)));
      sizes[c].h = std::max(1, static_cast<int>(std::ceil(source[c].h * scale)));
      widest = std::max(widest, sizes[c].w);
    }
    sizes[charts] = Rect{0, 0, kUnseenPatch, kUnseenPatch};
    for (int width = 64; width <= max_side; width *= 2) {
      if (width < widest) continue;
      const int height = PackShelves(sizes, width, &out.placed);
      if (height > 0 && (height <= width || (width * 2 > max_side && height <= max_side))) {
        out.width = width;
        out.height = (height + 3) / 4 * 4;
        break;
      }
    }
  }
  if (out.width == 0) {
    return MakeError(ErrorCode::kInternal,
                     fmt::format("cannot pack {} charts into a {} px atlas", charts, max_side));
  }
  out.scale = scale;
  return out;
}

static_assert(kChartMarginPx + 1 <= kTextureReadMarginPx, "texture.h promises to read no further");

cv::Mat DrawAtlas(const Charts& charts, const std::vector<Rect>& source, const Packing& packing,
                  const std::vector<cv::Mat>& images, const std::vector<cv::Point>& origins) {
  const std::vector<Rect>& placed = packing.placed;
  cv::Mat atlas(packing.height, packing.width, CV_8UC3, cv::Scalar(0, 0, 0));
  atlas(cv::Rect(placed[charts.count].x, placed[charts.count].y, kUnseenPatch, kUnseenPatch))
      .setTo(cv::Scalar(kUnseenColor[2], kUnseenColor[1], kUnseenColor[0]));
  // Each chart's own rectangle: on all cores.
  ParallelFor(0, charts.count, [&](std::size_t c) {
    const Rect& s = source[c];
    const Rect& d = placed[c];
    const cv::Point& origin = origins[charts.view[c]];
    const cv::Mat from = images[charts.view[c]](cv::Rect(s.x - origin.x, s.y - origin.y, s.w, s.h));
    cv::Mat to = atlas(cv::Rect(d.x, d.y, d.w, d.h));
    if (s.w == d.w && s.h == d.h) {
      from.copyTo(to);
    } else {
      cv::resize(from, to, to.size(), 0, 0, cv::INTER_AREA);
    }
  });
  return atlas;
}

void AssignUvs(const Charts& charts, ChartUvs&& projected, const Packing& packing, Mesh* mesh) {
  const std::vector<Rect>& placed = packing.placed;
  const std::vector<Rect>& source = projected.source;
  const float inv_w = 1.0f / packing.width;
  const float inv_h = 1.0f / packing.height;
  const int unseen = charts.count;
  const bool has_unseen = charts.start[unseen + 1] > charts.start[unseen];
  const std::vector<int>& uv_start = projected.start;
  std::vector<Eigen::Vector2f> uvs(uv_start.back() + (has_unseen ? 1 : 0));
  // Each chart's uvs from its vertices' pixels, on all cores.
  ParallelFor(0, charts.count, [&](std::size_t c) {
    const Rect& s = source[c];
    const Rect& d = placed[c];
    const float sx = static_cast<float>(d.w) / s.w;
    const float sy = static_cast<float>(d.h) / s.h;
    for (int i = uv_start[c]; i < uv_start[c + 1]; ++i) {
      // A vertex behind the camera maps to the rectangle's corner.
      const float u = projected.in_front[i] ? projected.u[i] : static_cast<float>(s.x);
      const float v = projected.in_front[i] ? projected.v[i] : static_cast<float>(s.y);
      // Image pixel centre u sits at texel coordinate d.x + (u - s.x + 0.5) * sx - 0.5.
      const float tx = d.x + (u - s.x + 0.5f) * sx;
      const float ty = d.y + (v - s.y + 0.5f) * sy;
      uvs[i] =
          Eigen::Vector2f(std::clamp(tx * inv_w, 0.0f, 1.0f), std::clamp(ty * inv_h, 0.0f, 1.0f));
    }
  });
  std::vector<Eigen::Vector3i> uv_faces = std::move(projected.uv_faces);
  if (has_unseen) {
    const int unseen_uv = uv_start.back();
    uvs[unseen_uv] = Eigen::Vector2f((placed[unseen].x + 0.5f * kUnseenPatch) * inv_w,
                                     (placed[unseen].y + 0.5f * kUnseenPatch) * inv_h);
    for (int k = charts.start[unseen]; k < charts.start[unseen + 1]; ++k) {
      uv_faces[charts.faces[k]] = Eigen::Vector3i::Constant(unseen_uv);
    }
  }
  mesh->uvs = std::move(uvs);
  mesh->uv_faces = std::move(uv_faces);
}

}  // namespace revolve::reconstruct::texture_internal
