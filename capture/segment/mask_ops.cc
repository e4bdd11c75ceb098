#include "capture/segment/mask_ops.h"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "base/mask_rect.h"

namespace revolve::capture {
namespace {

cv::Mat Kernel(int radius_px) {
  return cv::getStructuringElement(cv::MORPH_ELLIPSE,
                                   cv::Size(2 * radius_px + 1, 2 * radius_px + 1));
}

// Eight bytes from p as one word (any alignment).
std::uint64_t Word(const std::uint8_t* p) {
  std::uint64_t word;
  std::memcpy(&word, p, sizeof(word));
  return word;
}

// The first x in [from, end) where `through` is set and `filled` (0 or 255) is not, or `end`;
// eight pixels at a time where a word holds its bytes in little-endian order.
int FirstOpen(const std::uint8_t* through, const std::uint8_t* filled, int from, int end) {
  int x = from;
  if constexpr (std::endian::native == std::endian::little) {
    for (; x + 8 <= end; x += 8) {
      // A byte of `through` and not `filled`'s: non-zero exactly where the pixel is open.
      const std::uint64_t open = Word(through + x) & ~Word(filled + x);
      if (open != 0) return x + std::countr_zero(open) / 8;
    }
  }
  for (; x < end; ++x) {
    if (through[x] != 0 && filled[x] == 0) return x;
  }
  return end;
}

}  // namespace

cv::Mat GreyLevels(const cv::Mat& image) {
  cv::Mat grey;
  switch (image.channels()) {
    case 3:
      cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
      break;
    case 4:
      cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
      break;
    default:
      grey = image;
      break;
  }
  return grey;
}

cv::Mat OpenMask(const cv::Mat& mask, int radius_px) {
  if (radius_px <= 0) return mask;
  cv::Mat out;
  cv::morphologyEx(mask, out, cv::MORPH_OPEN, Kernel(radius_px));
  return out;
}

cv::Mat CloseMask(const cv::Mat& mask, int radius_px) {
  if (radius_px <= 0) return mask;
  cv::Mat out;
  cv::morphologyEx(mask, out, cv::MORPH_CLOSE, Kernel(radius_px));
  return out;
}

cv::Mat KeepLargestComponent(const cv::Mat& mask) {
  cv::Mat labels, stats, centroids;
  const int count = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  int best = 0;
  int best_area = 0;
  for (int label = 1; label < count; ++label) {
    const int area = stats.at<int>(label, cv::CC_STAT_AREA);
    if (area > best_area) {
      best = label;
      best_area = area;
    }
  }
  if (best == 0) return cv::Mat::zeros(mask.size(), CV_8UC1);
  cv::Mat out = labels == best;
  return out;
}

cv::Mat FillHoles(const cv::Mat& mask) {
  cv::Mat padded;
  cv::copyMakeBorder(mask, padded, 1, 1, 1, 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::floodFill(padded, cv::Point(0, 0), cv::Scalar(255), nullptr, cv::Scalar(), cv::Scalar(), 4);
  // What the flood did not reach is object or hole.
  cv::Mat out = padded(cv::Rect(1, 1, mask.cols, mask.rows)) == 0;
  out |= mask;
  return out;
}

cv::Mat FillHolesUpTo(const cv::Mat& mask, int max_area_px) {
  cv::Mat filled = FillHoles(mask);
  if (max_area_px <= 0) return filled;
  const cv::Mat holes = filled & ~mask;
  cv::Mat labels, stats, centroids;
  const int count = cv::connectedComponentsWithStats(holes, labels, stats, centroids, 4, CV_32S);
  for (int label = 1; label < count; ++label) {
    if (stats.at<int>(label, cv::CC_STAT_AREA) > max_area_px) filled.setTo(0, labels == label);
  }
  return filled;
}

int WorkFactor(cv::Size size) {
  const int side = std::max(size.width, size.height);
  for (int factor = side / kWorkSidePx; factor > 1; --factor) {
    if (size.width % factor == 0 && size.height % factor == 0) return factor;
  }
  return 1;
}

cv::Mat Reduced(const cv::Mat& image, int factor) {
  if (factor <= 1) return image;
  cv::Mat out;
  cv::resize(image, out, cv::Size(image.cols / factor, image.rows / factor), 0.0, 0.0,
             cv::INTER_AREA);
  return out;
}

MaskEdge EdgeOf(const cv::Mat& mask) {
  MaskEdge found;
  const cv::Rect object = MaskRect(mask);
  if (object.empty()) return found;
  found.part = cv::Rect(object.x - 1, object.y - 1, object.width + 2, object.height + 2) &
               cv::Rect(0, 0, mask.cols, mask.rows);
  cv::morphologyEx(mask(found.part), found.edge, cv::MORPH_GRADIENT, cv::Mat());
  return found;
}

cv::Mat Enlarged(const cv::Mat& mask, int factor, cv::Size full_size, const ImagePart& score,
                 const ImagePart& levels_part, const MaskEdge* edge) {
  const cv::Mat& levels = levels_part.values;
  if (factor <= 1 && levels.empty()) return mask;
  // Only around the object (its rectangle and a pixel more, where its edge is). Elsewhere the
  // enlarged mask is 0: for a factor that is a power of two, cv::resize's nearest pixel (the
  // floor of x / factor, exact) is the same for the part as for the whole, so only the part is
  // enlarged; for another, whose 1 / factor rounds, the whole is, as before.
  const MaskEdge found = edge != nullptr ? MaskEdge{} : EdgeOf(mask);
  const MaskEdge& at = edge != nullptr ? *edge : found;
  const cv::Rect& part = at.part;
  const cv::Mat& gradient = at.edge;
  cv::Mat full;
  if (factor >= 1 && std::has_single_bit(static_cast<unsigned>(factor)) &&
      full_size == cv::Size(mask.cols * factor, mask.rows * factor)) {
    full = cv::Mat::zeros(full_size, CV_8UC1);
    if (part.empty()) return full;
    const cv::Rect part_full(part.x * factor, part.y * factor, part.width * factor,
                             part.height * factor);
    cv::Mat enlarged = full(part_full);
    cv::resize(mask(part), enlarged, part_full.size(), 0.0, 0.0, cv::INTER_NEAREST);
  } else {
    cv::resize(mask, full, full_size, 0.0, 0.0, cv::INTER_NEAREST);
    if (part.empty()) return full;
  }
  const bool one_level = levels.total() == 1;
  const cv::Rect held = one_level ? cv::Rect() : cv::Rect(levels_part.origin, levels.size());
  for (int y = part.y; y < part.y + part.height; ++y) {
    const auto* e = gradient.ptr<std::uint8_t>(y - part.y) - part.x;
    const bool row_held = y >= held.y && y < held.y + held.height;
    const float* l = one_level  ? levels.ptr<float>(0)
                     : row_held ? levels.ptr<float>(y - held.y) - held.x
                                : nullptr;
    for (int x = part.x; x < part.x + part.width; ++x) {
      if (!e[x]) continue;
      if (!one_level && (l == nullptr || x < held.x || x >= held.x + held.width)) continue;
      const float level = one_level ? l[0] : l[x];
      if (level < 0.0f) continue;
      for (int dy = 0; dy < factor; ++dy) {
        const std::ptrdiff_t offset = static_cast<std::ptrdiff_t>(x) * factor;
        const auto* s = score.values.ptr<std::uint8_t>(y * factor + dy - score.origin.y) +
                        (offset - score.origin.x);
        auto* o = full.ptr<std::uint8_t>(y * factor + dy) + offset;
        for (int dx = 0; dx < factor; ++dx) o[dx] = s[dx] >= level ? 255 : 0;
      }
    }
  }
  return full;
}

// Filled run by run from each seed not yet reached (a scanline flood fill): the work is that of
// the pixels reached and the rows beside them, not a labelling of every component.
cv::Mat ConnectedThrough(const cv::Mat& through, const cv::Mat& seeds) {
  const int rows = through.rows;
  const int cols = through.cols;
  cv::Mat out = cv::Mat::zeros(through.size(), CV_8UC1);
  struct Run {
    int y, x0, x1;  // [x0, x1] of row y, filled; the rows beside it not yet looked at
  };
  std::vector<Run> pending;
  // Fills the run of `through` holding (x, y), a pixel of it not filled yet, and queues it.
  const auto fill_run = [&](int y, int x) {
    const std::uint8_t* a = through.ptr<std::uint8_t>(y);
    std::uint8_t* o = out.ptr<std::uint8_t>(y);
    int x0 = x;
    int x1 = x;
    while (x0 > 0 && a[x0 - 1] != 0 && o[x0 - 1] == 0) --x0;
    while (x1 + 1 < cols && a[x1 + 1] != 0 && o[x1 + 1] == 0) ++x1;
    std::fill(o + x0, o + x1 + 1, std::uint8_t{255});
    pending.push_back({y, x0, x1});
    return x1;
  };
  for (int y = 0; y < rows; ++y) {
    const std::uint8_t* s = seeds.ptr<std::uint8_t>(y);
    const std::uint8_t* a = through.ptr<std::uint8_t>(y);
    const std::uint8_t* o = out.ptr<std::uint8_t>(y);
    for (int x = 0; x < cols; ++x) {
      // Eight pixels at a time past rows of no seed.
      while (x + 8 <= cols && Word(s + x) == 0) x += 8;
      if (x >= cols) break;
      if (s[x] == 0 || a[x] == 0 || o[x] != 0) continue;
      fill_run(y, x);
      while (!pending.empty()) {
        const Run run = pending.back();
        pending.pop_back();
        // 8-connected: the rows above and below, one pixel past each end.
        for (const int ny : {run.y - 1, run.y + 1}) {
          if (ny < 0 || ny >= rows) continue;
          const std::uint8_t* na = through.ptr<std::uint8_t>(ny);
          const std::uint8_t* no = out.ptr<std::uint8_t>(ny);
          const int end = std::min(cols, run.x1 + 2);
          int nx = FirstOpen(na, no, std::max(0, run.x0 - 1), end);
          while (nx < end) nx = FirstOpen(na, no, fill_run(ny, nx) + 1, end);
        }
      }
    }
  }
  return out;
}

}  // namespace revolve::capture
