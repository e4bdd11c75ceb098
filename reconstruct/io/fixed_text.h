// Internal to reconstruct/io: the digits of the writers' numbers, inlined where they are written
// (writer_support.h's WriteFixed and WriteInt are these behind a call). Each function writes at
// `out` (room for kMaxNumberChars bytes: it may store a few bytes past its text) and returns the
// text's end.
#pragma once

#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace revolve::reconstruct::internal {

inline constexpr std::size_t kMaxNumberChars = 48;

static_assert(std::endian::native == std::endian::little,
              "the number texts are assembled in words, first character lowest");

// "00" "01" ... "99": two digits per division.
inline constexpr char kDigitPairs[] =
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
inline std::uint64_t Significant(std::uint64_t digits) {
  constexpr std::uint64_t kZeros = 0x3030303030303030ULL >> (8 * (8 - kWidth));
  // Zero bytes of `digits ^ kZeros` are '0' characters; the last digit always counts.
  const int leading =
      std::countr_zero((digits ^ kZeros) | (std::uint64_t{1} << (8 * (kWidth - 1)))) / 8;
  return digits >> (8 * leading);
}

// Writes Significant<kWidth>(digits) at `out` (stores 8 bytes); returns the end of the digits.
// (Not WriteWordText: counting the leading zeros of `digits` is shorter in the chain of `out`.)
template <int kWidth>
inline char* WriteSignificant(char* out, std::uint64_t digits) {
  constexpr std::uint64_t kZeros = 0x3030303030303030ULL >> (8 * (8 - kWidth));
  const int leading =
      std::countr_zero((digits ^ kZeros) | (std::uint64_t{1} << (8 * (kWidth - 1)))) / 8;
  digits >>= 8 * leading;
  std::memcpy(out, &digits, 8);
  return out + kWidth - leading;
}

// Decimal digits of `value`, most significant first; may store up to 8 bytes past them.
inline char* WriteUnsigned(char* out, unsigned long long value) {
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
inline char* WriteFraction(char* out, std::uint64_t digits) {
  static_assert(kDecimals >= 1 && kDecimals <= 7);
  constexpr std::uint64_t kZeros = 0x3030303030303030ULL >> (8 * (8 - kDecimals));
  const std::uint64_t nonzero = digits ^ kZeros;  // zero bytes: '0' characters
  const int trailing = std::countl_zero(nonzero << (64 - 8 * kDecimals)) / 8;
  const std::uint64_t text = '.' | (digits << 8);
  std::memcpy(out, &text, 8);
  return out + (nonzero == 0 ? 0 : 1 + kDecimals - trailing);
}

// WriteFixed (writer_support.h) with the number of decimals known at compile time (constant
// factors and divisors), inlined where the writers call it per coordinate.
template <int kDecimals>
[[gnu::always_inline]] inline char* WriteFixedN(char* out, float value) {
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
  // The sign from the float's bits, without a branch (coordinates' signs are unpredictable):
  // the same as scaled < 0 but where the value rounds to 0 (-0 too), which gets none.
  *out = '-';
  out += (std::bit_cast<std::uint32_t>(value) >> 31) & static_cast<std::uint32_t>(magnitude != 0);
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

}  // namespace revolve::reconstruct::internal
