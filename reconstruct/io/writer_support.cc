#include "reconstruct/io/writer_support.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>

#include <fmt/format.h>

namespace revolve::reconstruct::internal {

char* WriteInt(char* out, long long value) {
  if (value < 0) {
    *out++ = '-';
    return WriteUnsigned(out, 0ULL - static_cast<unsigned long long>(value));
  }
  return WriteUnsigned(out, static_cast<unsigned long long>(value));
}

char* WriteFixed(char* out, float value, int decimals) {
  switch (std::clamp(decimals, 0, 9)) {
    case 0:
      return WriteFixedN<0>(out, value);
    case 1:
      return WriteFixedN<1>(out, value);
    case 2:
      return WriteFixedN<2>(out, value);
    case 3:
      return WriteFixedN<3>(out, value);
    case 4:
      return WriteFixedN<4>(out, value);
    case 5:
      return WriteFixedN<5>(out, value);
    case 6:
      return WriteFixedN<6>(out, value);
    case 7:
      return WriteFixedN<7>(out, value);
    case 8:
      return WriteFixedN<8>(out, value);
    default:
      return WriteFixedN<9>(out, value);
  }
}

std::uint64_t WordText(std::string_view text) {
  const std::size_t size = std::min<std::size_t>(text.size(), 7);
  std::uint64_t word = std::uint64_t{size} << 56;
  std::memcpy(&word, text.data(), size);  // the low bytes (little-endian host)
  return word;
}

std::array<std::uint64_t, 256> ChannelTexts(std::string_view prefix) {
  std::array<std::uint64_t, 256> words;
  for (int k = 0; k < 256; ++k) {
    char text[kMaxNumberChars + 8];
    const std::size_t n = std::min<std::size_t>(prefix.size(), 8);
    std::memcpy(text, prefix.data(), n);
    words[k] =
        WordText(std::string_view(text, WriteFixed(text + n, static_cast<float>(k / 255.0), 4)));
  }
  return words;
}

IndexTexts::IndexTexts(int first, std::size_t count) : first_(first) {
  if (first < 0 || static_cast<unsigned long long>(first) + count > 10000000) {
    return;  // a minus sign or 8 digits: formatted on the spot
  }
  words_.resize(count);
  // In runs of equal ten-thousands (value / 10^4): their digits once, then the last four.
  auto length = [](std::uint64_t text) { return std::uint64_t{8} - std::countl_zero(text) / 8; };
  const auto begin = static_cast<std::uint32_t>(first);
  const auto end = static_cast<std::uint32_t>(first + count);
  std::uint64_t* word = words_.data();
  for (std::uint32_t value = begin; value < end;) {
    const std::uint32_t high = value / 10000;
    const std::uint32_t run_end = std::min(end, (high + 1) * 10000);
    if (high == 0) {
      for (; value < run_end; ++value) {
        const std::uint64_t text = Significant<4>(FourDigits(value));
        *word++ = text | (length(text) << 56);
      }
    } else {
      const std::uint64_t prefix = Significant<4>(FourDigits(high));
      const std::uint64_t prefix_length = length(prefix);
      const std::uint64_t tag = (prefix_length + 4) << 56;
      for (; value < run_end; ++value) {
        *word++ = prefix | (FourDigits(value - high * 10000) << (8 * prefix_length)) | tag;
      }
    }
  }
}

const VertexTexts& VertexTexts::Of(const Mesh& mesh) {
  std::call_once(made_, [&] {
    const std::size_t n = mesh.vertices.size();
    start_.resize(n + 1);
    text_.resize(32 * n + kMaxText + kCopyBytes);  // about what 4-decimal millimetres take
    std::size_t at = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (text_.size() - at < kMaxText + kCopyBytes) text_.resize(2 * text_.size());
      start_[i] = at;
      char* p = text_.data() + at;
      for (int k = 0; k < 3; ++k) {
        p = WriteFixedN<4>(p, mesh.vertices[i][k]);
        *p++ = ' ';
      }
      at = static_cast<std::size_t>(p - 1 - text_.data());  // no space after the last
    }
    start_[n] = at;
    text_.resize(at + kCopyBytes);
  });
  return *this;
}

Error BadFile(const std::filesystem::path& path, std::string_view what) {
  return Error{ErrorCode::kBadInput, fmt::format("{}: {}", path.string(), what)};
}

Error AbandonedFile(const std::filesystem::path& path) {
  return Error{ErrorCode::kAborted,
               fmt::format("{}: not written: the model was abandoned before it was finished",
                           path.string())};
}

void StageGate::Reach(MeshStage stage) {
  {
    const std::lock_guard lock(mutex_);
    reached_ = std::max(reached_, static_cast<int>(stage));
  }
  changed_.notify_all();
}

void StageGate::Abandon() {
  {
    const std::lock_guard lock(mutex_);
    abandoned_ = true;
  }
  changed_.notify_all();
}

std::optional<MeshStage> StageGate::Wait(MeshStage stage) const {
  std::unique_lock lock(mutex_);
  changed_.wait(lock, [&] { return abandoned_ || reached_ >= static_cast<int>(stage); });
  if (abandoned_) return std::nullopt;
  return static_cast<MeshStage>(reached_);
}

}  // namespace revolve::reconstruct::internal
