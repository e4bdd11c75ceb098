#include "capture/segment/colour_cut.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include <opencv2/imgproc.hpp>
#include <opencv2/imgproc/detail/gcgraph.hpp>

namespace revolve::capture {
namespace {

constexpr int kLevels = 16;

// An index computed in int (image sizes fit), as a container subscript.
std::size_t At(int index) { return static_cast<std::size_t>(index); }
constexpr int kBins = kLevels * kLevels * kLevels;
// The prior's share of a colour histogram (Costs).
constexpr double kPriorShare = 0.1;

// Colour level (0..15) of an 8-bit value on a square-root scale: levels 0..3 cover 0..15, so the
// dark shadows of an object stay apart from a black backdrop.
std::array<std::uint16_t, 256> LevelTable() {
  std::array<std::uint16_t, 256> table{};
  for (int v = 0; v < 256; ++v) {
    table[static_cast<std::size_t>(v)] = static_cast<std::uint16_t>(
        std::min(kLevels - 1, static_cast<int>(std::sqrt(v / 255.0) * kLevels)));
  }
  return table;
}

// A histogram smoothed by [1 2 1] / 4 along each axis (neighbouring levels share their counts;
// the end levels count themselves as their missing neighbour).
std::vector<float> Smoothed(const std::vector<float>& histogram) {
  std::vector<float> a = histogram, b(kBins);
  // Along the axis of `stride`: the bins as rows of kLevels levels, `stride` apart, starting at
  // each bin whose level on that axis is 0.
  for (const std::ptrdiff_t stride :
       {std::ptrdiff_t{1}, std::ptrdiff_t{kLevels}, std::ptrdiff_t{kLevels} * kLevels}) {
    for (std::ptrdiff_t first = 0; first < kBins; ++first) {
      if ((first / stride) % kLevels != 0) continue;
      const float* in = a.data() + first;
      float* out = b.data() + first;
      for (std::ptrdiff_t level = 0; level < kLevels; ++level) {
        const float here = in[level * stride];
        const float left = level > 0 ? in[(level - 1) * stride] : here;
        const float right = level + 1 < kLevels ? in[(level + 1) * stride] : here;
        out[level * stride] = 0.25f * left + 0.5f * here + 0.25f * right;
      }
    }
    a.swap(b);
  }
  return a;
}

// -log of each bin's share of the histogram, a tenth of its count added spread evenly over the
// bins: a colour never seen costs the same finite amount in both models, whatever the sizes of
// their samples. (One count added to every bin made the prior ~4096 counts, as much as a small
// object's own pixels: its rarer colours, the deep shadows on it, then cost it more than they
// cost the larger backdrop.)
// Only the bins in `needed` are filled (the others are left 0): a cut reads the costs of its
// band's colours alone.
std::vector<float> Costs(const std::vector<float>& histogram, const std::vector<int>& needed) {
  const std::vector<float> smooth = Smoothed(histogram);
  double count = 0.0;
  for (float h : smooth) count += h;
  const double prior = kPriorShare * count / kBins;
  const double total = count + kPriorShare * count;
  std::vector<float> cost(kBins);
  for (const int i : needed) {
    cost[static_cast<std::size_t>(i)] =
        static_cast<float>(-std::log((smooth[static_cast<std::size_t>(i)] + prior) / total));
  }
  return cost;
}

// Capacities in fixed point (1/64): the max-flow's augmenting paths end on exact zeros.
int Fixed(float weight) { return static_cast<int>(std::lround(64.0f * weight)); }

bool IsObject(std::uint8_t label) { return label == cv::GC_FGD || label == cv::GC_PR_FGD; }
bool IsSure(std::uint8_t label) { return label == cv::GC_FGD || label == cv::GC_BGD; }

int SquaredDistance(const cv::Vec3b& a, const cv::Vec3b& b) {
  const int d0 = int(a[0]) - int(b[0]), d1 = int(a[1]) - int(b[1]), d2 = int(a[2]) - int(b[2]);
  return d0 * d0 + d1 * d1 + d2 * d2;
}

// The graph's fixed part: the undecided pixels, the cuts between them and what their sure
// neighbours pull towards either side.
struct Band {
  std::vector<int> pixel;          // vertex -> pixel index (y * cols + x)
  std::vector<float> to_object;    // vertex -> summed weights of sure-object neighbours
  std::vector<float> to_backdrop;  // vertex -> summed weights of sure-backdrop neighbours
  struct Link {
    int a, b;
    float weight;
  };
  std::vector<Link> links;
};

// The 4 neighbours already visited in raster order (left, up-left, up, up-right), with the
// distance weight of each.
constexpr int kBackDx[4] = {-1, -1, 0, 1};
constexpr int kBackDy[4] = {0, -1, -1, -1};

// 1 / (2 mean) of the squared colour differences of the pairs of neighbours in kBackDx/kBackDy.
// The sum is of whole numbers, exact in 64 bits (as in the double it was: below 2^53), and each
// neighbour's pairs are summed along a row with no test per pixel.
double Beta(const cv::Mat& bgr) {
  std::int64_t sum = 0;
  std::int64_t count = 0;
  const int cols = bgr.cols;
  // Summed in 32 bits over stretches of kStretch pairs (each at most 3 * 255^2), then in 64.
  constexpr int kStretch = 8192;
  const auto pairs = [&](const cv::Vec3b* p, const cv::Vec3b* q, int begin, int end) {
    for (int from = begin; from < end; from += kStretch) {
      const int to = std::min(end, from + kStretch);
      std::int32_t stretch_sum = 0;
      for (int x = from; x < to; ++x) stretch_sum += SquaredDistance(p[x], q[x]);
      sum += stretch_sum;
    }
    count += std::max(0, end - begin);
  };
  for (int y = 0; y < bgr.rows; ++y) {
    const auto* p = bgr.ptr<cv::Vec3b>(y);
    pairs(p, p - 1, 1, cols);  // left
    if (y == 0) continue;
    const auto* up = bgr.ptr<cv::Vec3b>(y - 1);
    pairs(p, up - 1, 1, cols);      // up-left
    pairs(p, up, 0, cols);          // up
    pairs(p, up + 1, 0, cols - 1);  // up-right
  }
  return sum > 0 ? 1.0 / (2.0 * static_cast<double>(sum) / static_cast<double>(count)) : 0.0;
}

Band BandOf(const cv::Mat& bgr, const cv::Mat& labels, const ColourCutOptions& options,
            std::vector<int>& vertex_of) {
  Band band;
  const double beta = Beta(bgr);
  const float diagonal = static_cast<float>(options.smoothness / std::sqrt(2.0));
  const float straight = static_cast<float>(options.smoothness);
  vertex_of.assign(static_cast<std::size_t>(bgr.total()), -1);
  for (int y = 0; y < bgr.rows; ++y) {
    const auto* l = labels.ptr<std::uint8_t>(y);
    for (int x = 0; x < bgr.cols; ++x) {
      if (IsSure(l[x])) continue;
      vertex_of[At(y * bgr.cols + x)] = static_cast<int>(band.pixel.size());
      band.pixel.push_back(y * bgr.cols + x);
    }
  }
  band.to_object.assign(band.pixel.size(), 0.0f);
  band.to_backdrop.assign(band.pixel.size(), 0.0f);
  // The pixels with a link: a vertex, or a pixel one of whose neighbours in kBackDx/kBackDy is
  // (the others add nothing; those are visited in the same raster order).
  const int cols = bgr.cols;
  std::vector<std::uint8_t> linked(static_cast<std::size_t>(cols));
  for (int y = 0; y < bgr.rows; ++y) {
    const auto* p = bgr.ptr<cv::Vec3b>(y);
    const auto* l = labels.ptr<std::uint8_t>(y);
    const int* here = vertex_of.data() + static_cast<std::ptrdiff_t>(y) * cols;
    const int* up = y > 0 ? here - cols : nullptr;
    for (int x = 0; x < cols; ++x) {
      bool any = here[x] >= 0 || (x > 0 && here[x - 1] >= 0);
      if (up != nullptr) {
        any = any || (x > 0 && up[x - 1] >= 0) || up[x] >= 0 || (x + 1 < cols && up[x + 1] >= 0);
      }
      linked[static_cast<std::size_t>(x)] = any ? 1 : 0;
    }
    for (int x = 0; x < cols; ++x) {
      if (linked[static_cast<std::size_t>(x)] == 0) continue;
      const int v = vertex_of[At(y * bgr.cols + x)];
      for (int k = 0; k < 4; ++k) {
        const int nx = x + kBackDx[k], ny = y + kBackDy[k];
        if (nx < 0 || nx >= bgr.cols || ny < 0) continue;
        const int u = vertex_of[At(ny * bgr.cols + nx)];
        if (v < 0 && u < 0) continue;
        const float weight =
            (kBackDy[k] != 0 && kBackDx[k] != 0 ? diagonal : straight) *
            static_cast<float>(std::exp(-beta * SquaredDistance(p[x], bgr.ptr<cv::Vec3b>(ny)[nx])));
        if (v >= 0 && u >= 0) {
          band.links.push_back({v, u, weight});
        } else if (v >= 0) {
          (labels.ptr<std::uint8_t>(ny)[nx] == cv::GC_FGD
               ? band.to_object
               : band.to_backdrop)[static_cast<std::size_t>(v)] += weight;
        } else {
          (l[x] == cv::GC_FGD ? band.to_object : band.to_backdrop)[static_cast<std::size_t>(u)] +=
              weight;
        }
      }
    }
  }
  return band;
}

}  // namespace

bool CutByColour(const cv::Mat& bgr, cv::Mat& labels, const ColourCutOptions& options,
                 const cv::Mat& object_samples) {
  static const std::array<std::uint16_t, 256> level = LevelTable();
  cv::Mat bins(bgr.size(), CV_16UC1);
  bool has_object = false, has_backdrop = false;
  for (int y = 0; y < bgr.rows; ++y) {
    const auto* p = bgr.ptr<cv::Vec3b>(y);
    const auto* l = labels.ptr<std::uint8_t>(y);
    auto* b = bins.ptr<std::uint16_t>(y);
    for (int x = 0; x < bgr.cols; ++x) {
      b[x] = static_cast<std::uint16_t>(level[p[x][0]] + kLevels * level[p[x][1]] +
                                        kLevels * kLevels * level[p[x][2]]);
      (IsObject(l[x]) ? has_object : has_backdrop) = true;
    }
  }
  if (!has_object || !has_backdrop) return false;
  std::vector<int> vertex_of;
  const Band band = BandOf(bgr, labels, options, vertex_of);
  if (band.pixel.empty()) return true;
  const auto* bin = bins.ptr<std::uint16_t>(0);  // continuous: created above
  const bool continuous = labels.isContinuous();
  cv::Mat work = continuous ? labels : labels.clone();
  auto* label = work.ptr<std::uint8_t>(0);
  // The samples as one row of the image's pixels (null: none).
  const cv::Mat samples = object_samples.empty() || object_samples.isContinuous()
                              ? object_samples
                              : object_samples.clone();
  const std::uint8_t* sample = samples.empty() ? nullptr : samples.ptr<std::uint8_t>(0);
  // The band's colours (the bins whose costs the cut reads).
  std::vector<int> band_bins;
  {
    std::vector<char> seen(kBins, 0);
    for (const int pixel : band.pixel) {
      const std::uint16_t b = bin[pixel];
      if (!seen[b]) band_bins.push_back(b);
      seen[b] = 1;
    }
  }
  // The graph's vertices and links, made once: each iteration cuts a copy with its own terminal
  // weights (a fresh graph made in the same order is the same graph: the links leave the
  // vertices' weights and the flow as they are, and maxFlow sets up the rest).
  cv::detail::GCGraph<int> links(static_cast<unsigned>(band.pixel.size()),
                                 static_cast<unsigned>(2 * band.links.size()));
  for (std::size_t v = 0; v < band.pixel.size(); ++v) links.addVtx();
  for (const Band::Link& link : band.links)
    links.addEdges(link.a, link.b, Fixed(link.weight), Fixed(link.weight));
  // The colour models' counts: those of the sure pixels (and the samples) once, the band's by its
  // labels at each iteration. Whole counts, exact in a float (a crop holds fewer than 2^24
  // pixels): the histograms a count of every pixel at each iteration gave.
  std::vector<int> sure_object(kBins, 0), sure_backdrop(kBins, 0);
  const std::size_t pixels = bgr.total();
  for (std::size_t i = 0; i < pixels; ++i) {
    if (vertex_of[i] >= 0) continue;
    const bool as_object = IsObject(label[i]) || (sample != nullptr && sample[i] != 0);
    ++(as_object ? sure_object : sure_backdrop)[bin[i]];
  }
  for (int iteration = 0; iteration < options.iterations; ++iteration) {
    std::vector<int> object_count = sure_object, backdrop_count = sure_backdrop;
    for (const int i : band.pixel) {
      const bool as_object = IsObject(label[i]) || (sample != nullptr && sample[i] != 0);
      ++(as_object ? object_count : backdrop_count)[bin[i]];
    }
    std::vector<float> object(kBins), backdrop(kBins);
    for (int b = 0; b < kBins; ++b) {
      object[At(b)] = static_cast<float>(object_count[At(b)]);
      backdrop[At(b)] = static_cast<float>(backdrop_count[At(b)]);
    }
    const std::vector<float> object_cost = Costs(object, band_bins);
    const std::vector<float> backdrop_cost = Costs(backdrop, band_bins);
    cv::detail::GCGraph<int> graph = links;
    for (std::size_t v = 0; v < band.pixel.size(); ++v) {
      const std::uint16_t b = bin[band.pixel[v]];
      // Source = object: cutting a pixel from the source costs its backdrop cost, and its sure
      // object neighbours' links.
      graph.addTermWeights(static_cast<int>(v), Fixed(backdrop_cost[b] + band.to_object[v]),
                           Fixed(object_cost[b] + band.to_backdrop[v]));
    }
    graph.maxFlow();
    bool changed = false;
    for (std::size_t v = 0; v < band.pixel.size(); ++v) {
      const std::uint8_t now =
          graph.inSourceSegment(static_cast<int>(v)) ? cv::GC_PR_FGD : cv::GC_PR_BGD;
      changed |= label[band.pixel[v]] != now;
      label[band.pixel[v]] = now;
    }
    if (!changed) break;
  }
  if (!continuous) work.copyTo(labels);
  return true;
}

}  // namespace revolve::capture
