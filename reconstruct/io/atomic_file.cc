#include "reconstruct/io/atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

namespace revolve::reconstruct::internal {
namespace {

namespace fs = std::filesystem;

Error IoError(const fs::path& path, std::string_view what, int err) {
  return Error{ErrorCode::kIo, fmt::format("{}: {}: {}", path.string(), what, std::strerror(err))};
}

fs::path DirectoryOf(const fs::path& path) {
  fs::path dir = path.parent_path();
  return dir.empty() ? fs::path(".") : dir;
}

}  // namespace

AtomicFile::~AtomicFile() {
  if (!temp_.empty()) {
    fd_.Close();
    ::unlink(temp_.c_str());
  }
}

Expected<void> AtomicFile::Open() {
  std::string name =
      (DirectoryOf(path_) / ("." + path_.filename().string() + ".tmp-XXXXXX")).string();
  const int fd = ::mkstemp(name.data());
  if (fd < 0) {
    return std::unexpected(IoError(path_, "cannot create the file", errno));
  }
  fd_ = UniqueFd(fd);
  temp_ = name;
  ::fchmod(fd, 0644);
  buffer_.reserve(kBufferSize);
  return {};
}

Expected<void> AtomicFile::Commit() {
  Flush();
  if (write_errno_ != 0) {
    return std::unexpected(IoError(path_, "cannot write", write_errno_));
  }
  if (::fsync(fd_.get()) != 0) {
    return std::unexpected(IoError(path_, "cannot sync", errno));
  }
  if (const int err = fd_.Close(); err != 0) {
    return std::unexpected(IoError(path_, "cannot close", err));
  }
  if (::rename(temp_.c_str(), path_.c_str()) != 0) {
    return std::unexpected(IoError(path_, "cannot rename the finished file into place", errno));
  }
  temp_.clear();
  // Make the rename itself durable.
  UniqueFd dir_fd(::open(DirectoryOf(path_).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (dir_fd.get() >= 0) {
    ::fsync(dir_fd.get());
  }
  return {};
}

void AtomicFile::Flush() {
  WriteAll(buffer_);
  buffer_.clear();
}

void AtomicFile::WriteAll(std::string_view bytes) {
  std::size_t done = 0;
  while (write_errno_ == 0 && done < bytes.size()) {
    const ssize_t n = ::write(fd_.get(), bytes.data() + done, bytes.size() - done);
    if (n < 0) {
      if (errno == EINTR) {
        continue;
      }
      write_errno_ = errno;
    } else {
      done += static_cast<std::size_t>(n);
    }
  }
}

Expected<void> WriteFileAtomically(const fs::path& path, std::string_view bytes) {
  AtomicFile file(path);
  if (Expected<void> opened = file.Open(); !opened) {
    return opened;
  }
  file.Append(bytes);
  return file.Commit();
}

void AppendFloat(std::string* out, float value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out->append(buffer, result.ptr);
}

void AppendInt(std::string* out, long long value) {
  char buffer[kMaxNumberChars];
  out->append(buffer, WriteInt(buffer, value));
}

void AppendFixed(std::string* out, float value, int decimals) {
  char buffer[kMaxNumberChars];
  out->append(buffer, WriteFixed(buffer, value, decimals));
}

namespace {

// "00" "01" ... "99": two digits per division.
constexpr char kDigitPairs[] =
    "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
    "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
    "8081828384858687888990919293949596979899";

// Decimal digits of `value`, most significant first, written in place (no copy of a
// variable length).
char* WriteUnsigned(char* out, unsigned long long value) {
  int count = 1;
  for (unsigned long long bound = 10; count < 20 && value >= bound; bound *= 10) ++count;
  char* const end = out + count;
  char* p = end;
  while (value >= 100) {
    const auto pair = static_cast<std::size_t>(value % 100);
    value /= 100;
    p -= 2;
    std::memcpy(p, kDigitPairs + 2 * pair, 2);
  }
  if (value >= 10) {
    std::memcpy(p - 2, kDigitPairs + 2 * value, 2);
  } else {
    p[-1] = static_cast<char>('0' + value);
  }
  return end;
}

// WriteFixed with the number of decimals known at compile time (constant divisors).
// `magnitude`: |value| * 10^kDecimals rounded; `negative`: a minus sign when magnitude > 0.
template <int kDecimals>
char* WriteFixedN(char* out, unsigned long long magnitude, bool negative) {
  constexpr unsigned long long kScale = [] {
    unsigned long long p = 1;
    for (int d = 0; d < kDecimals; ++d) p *= 10;
    return p;
  }();
  if (negative && magnitude > 0) {
    *out++ = '-';
  }
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

}  // namespace

char* WriteInt(char* out, long long value) {
  if (value < 0) {
    *out++ = '-';
    return WriteUnsigned(out, 0ULL - static_cast<unsigned long long>(value));
  }
  return WriteUnsigned(out, static_cast<unsigned long long>(value));
}

char* WriteFixed(char* out, float value, int decimals) {
  static constexpr double kPow10[] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9};
  decimals = std::clamp(decimals, 0, 9);
  const double scaled = static_cast<double>(value) * kPow10[decimals];
  const double magnitude = std::abs(scaled);
  if (!(magnitude <= 1e17)) {  // NaN, infinite or too large for the integer path
    return std::to_chars(out, out + kMaxNumberChars, value).ptr;
  }
  // Rounded half away from zero, as std::round: below 0.5 it is 0; above, m + 0.5 is exact or
  // rounds within the same integer, so truncating it rounds m.
  // NOLINTNEXTLINE(bugprone-incorrect-roundings): the case it warns about (m < 0.5) is excluded.
  const auto q = magnitude < 0.5 ? 0ULL : static_cast<unsigned long long>(magnitude + 0.5);
  const bool negative = scaled < 0.0;
  switch (decimals) {
    case 0:
      return WriteFixedN<0>(out, q, negative);
    case 1:
      return WriteFixedN<1>(out, q, negative);
    case 2:
      return WriteFixedN<2>(out, q, negative);
    case 3:
      return WriteFixedN<3>(out, q, negative);
    case 4:
      return WriteFixedN<4>(out, q, negative);
    case 5:
      return WriteFixedN<5>(out, q, negative);
    case 6:
      return WriteFixedN<6>(out, q, negative);
    case 7:
      return WriteFixedN<7>(out, q, negative);
    case 8:
      return WriteFixedN<8>(out, q, negative);
    default:
      return WriteFixedN<9>(out, q, negative);
  }
}

void TextOut::Put(std::string_view text) {
  if (text.size() > kRoomMax) {
    Flush();
    file_->Append(text);
    return;
  }
  char* p = Room(text.size());
  std::memcpy(p, text.data(), text.size());
  End(p + text.size());
}

void TextOut::Flush() {
  file_->Append(std::string_view(buffer_.data(), end_));
  end_ = 0;
}

Expected<std::string> ReadWholeFile(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    return MakeError(ErrorCode::kNotFound, fmt::format("{}: no such file", path.string()));
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return MakeError(ErrorCode::kIo, fmt::format("{}: cannot open", path.string()));
  std::ostringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

Error BadFile(const std::filesystem::path& path, std::string_view what) {
  return Error{ErrorCode::kBadInput, fmt::format("{}: {}", path.string(), what)};
}

}  // namespace revolve::reconstruct::internal
