#include "reconstruct/io/writer_support.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>

#include <fmt/format.h>

namespace revolve::reconstruct::internal {

namespace {

static_assert(std::endian::native == std::endian::little,
              "the number texts are assembled in words, first character lowest");

// "00" "01" ... "99": two digits per division.
constexpr char kDigitPairs[] =
    "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
    "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
    "8081828384858687888990919293949596979899";

// Four characters "0000".."9999" of `value` < 10^4 in the low bytes of a word, the first
// character in the lowest byte (the order they have in memory on this little-endian host).
inline std::uint64_t FourDigits(std::uint32_t value) {
  std::uint16_t high;
  std::uint16_t low;
  std::memcpy(&high, kDigitPairs + std::size_t{2} * (value / 100), 2);
  std::memcpy(&low, kDigitPairs + std::size_t{2} * (value % 100), 2);
  return high | (std::uint64_t{low} << 16);
}

// Eight characters "00000000".."99999999" of `value` < 10^8, as FourDigits.
inline std::uint64_t EightDigits(std::uint32_t value) {
  return FourDigits(value / 10000) | (FourDigits(value % 10000) << 32);
}

// The `kWidth` zero-padded digit characters in `digits` without their leading zeros (one digit
// stays), as a WordText.
template <int kWidth>
std::uint64_t Significant(std::uint64_t digits) {
  constexpr std::uint64_t kZeros = 0x3030303030303030ULL >> (8 * (8 - kWidth));
  // Zero bytes of `digits ^ kZeros` are '0' characters; the last digit always counts.
  const int leading =
      std::countr_zero((digits ^ kZeros) | (std::uint64_t{1} << (8 * (kWidth - 1)))) / 8;
  return digits >> (8 * leading);
}

// Writes Significant<kWidth>(digits) at `out` (stores 8 bytes); returns the end of the digits.
// (Not WriteWordText: counting the leading zeros of `digits` is shorter in the chain of `out`.)
template <int kWidth>
char* WriteSignificant(char* out, std::uint64_t digits) {
  constexpr std::uint64_t kZeros = 0x3030303030303030ULL >> (8 * (8 - kWidth));
  const int leading =
      std::countr_zero((digits ^ kZeros) | (std::uint64_t{1} << (8 * (kWidth - 1)))) / 8;
  digits >>= 8 * leading;
  std::memcpy(out, &digits, 8);
  return out + kWidth - leading;
}

// Decimal digits of `value`, most significant first; may store up to 8 bytes past them.
char* WriteUnsigned(char* out, unsigned long long value) {
  if (value < 10000) {
    return WriteSignificant<4>(out, FourDigits(static_cast<std::uint32_t>(value)));
  }
  if (value < 100000000) {
    return WriteSignificant<8>(out, EightDigits(static_cast<std::uint32_t>(value)));
  }
  out = WriteUnsigned(out, value / 100000000);
  const std::uint64_t low = EightDigits(static_cast<std::uint32_t>(value % 100000000));
  std::memcpy(out, &low, 8);
  return out + 8;
}

// The fraction's `kDecimals` digit characters in `digits` (a word, first digit lowest) written
// after a '.', trailing '0's dropped; nothing when all are '0'. Stores 8 bytes at `out`.
template <int kDecimals>
char* WriteFraction(char* out, std::uint64_t digits) {
  static_assert(kDecimals >= 1 && kDecimals <= 7);
  constexpr std::uint64_t kZeros = 0x3030303030303030ULL >> (8 * (8 - kDecimals));
  const std::uint64_t nonzero = digits ^ kZeros;  // zero bytes: '0' characters
  const int trailing = std::countl_zero(nonzero << (64 - 8 * kDecimals)) / 8;
  const std::uint64_t text = '.' | (digits << 8);
  std::memcpy(out, &text, 8);
  return out + (nonzero == 0 ? 0 : 1 + kDecimals - trailing);
}

// WriteFixed with the number of decimals known at compile time (constant factors and divisors).
template <int kDecimals>
char* WriteFixedN(char* out, float value) {
  constexpr unsigned long long kScale = [] {
    unsigned long long p = 1;
    for (int d = 0; d < kDecimals; ++d) p *= 10;
    return p;
  }();
  const double scaled = static_cast<double>(value) * static_cast<double>(kScale);
  const double m = std::abs(scaled);
  if (!(m <= 1e17)) {  // NaN, infinite or too large for the integer path
    return std::to_chars(out, out + kMaxNumberChars, value).ptr;
  }
  // m rounded half away from zero, as std::round: below 0.5 it is 0; above, m + 0.5 is exact or
  // rounds within the same integer, so truncating it rounds m.
  // NOLINTNEXTLINE(bugprone-incorrect-roundings): the case it warns about (m < 0.5) is excluded.
  const auto nearest = static_cast<unsigned long long>(static_cast<long long>(m + 0.5));
  const unsigned long long magnitude = m < 0.5 ? 0 : nearest;
  *out = '-';
  out += scaled < 0.0 && magnitude > 0 ? 1 : 0;
  if constexpr (kDecimals == 0) {
    return WriteUnsigned(out, magnitude);
  } else if constexpr (kDecimals <= 7) {
    if (magnitude < 100000000) {
      // The common case: all digits from one split, the integer part in the low 8 - kDecimals
      // characters, the fraction in the high kDecimals.
      constexpr int kIntegerWidth = 8 - kDecimals;
      const std::uint64_t digits = EightDigits(static_cast<std::uint32_t>(magnitude));
      out = WriteSignificant<kIntegerWidth>(
          out, digits & ((std::uint64_t{1} << (8 * kIntegerWidth)) - 1));
      return WriteFraction<kDecimals>(out, digits >> (8 * kIntegerWidth));
    }
    out = WriteUnsigned(out, magnitude / kScale);
    const auto fraction = static_cast<std::uint32_t>(magnitude % kScale);
    if constexpr (kDecimals <= 4) {
      return WriteFraction<kDecimals>(out, FourDigits(fraction) >> (8 * (4 - kDecimals)));
    } else {
      return WriteFraction<kDecimals>(out, EightDigits(fraction) >> (8 * (8 - kDecimals)));
    }
  } else {
    out = WriteUnsigned(out, magnitude / kScale);
    unsigned long long fraction = magnitude % kScale;
    if (fraction == 0) {
      return out;
    }
    int digits = kDecimals;
    while (fraction % 10 == 0) {
      fraction /= 10;
      --digits;
    }
    *out = '.';
    int d = digits;
    for (; d >= 2; d -= 2) {
      std::memcpy(out + d - 1, kDigitPairs + 2 * (fraction % 100), 2);
      fraction /= 100;
    }
    if (d == 1) {
      out[1] = static_cast<char>('0' + fraction);
    }
    return out + digits + 1;
  }
}

}  // namespace

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
