#include "reconstruct/cameras/camera_file.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include <fmt/format.h>
#include <Eigen/LU>
#include <Eigen/QR>

#include "base/text_file.h"

namespace revolve::reconstruct {
namespace {

constexpr int kMiddleburyNumbers = 21;
constexpr int kProjectionNumbers = 12;

std::vector<std::string_view> Tokens(std::string_view line) {
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    std::size_t j = i;
    while (j < line.size() && !std::isspace(static_cast<unsigned char>(line[j]))) ++j;
    if (j > i) tokens.push_back(line.substr(i, j - i));
    i = j;
  }
  return tokens;
}

bool ParseDouble(std::string_view token, double* value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), *value);
  return ec == std::errc() && end == token.data() + token.size() && std::isfinite(*value);
}

bool ParseCount(std::string_view token, int* value) {
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), *value);
  return ec == std::errc() && end == token.data() + token.size() && *value >= 0;
}

std::string Stem(std::string_view name) {
  const std::filesystem::path path{std::string(name)};
  return path.stem().string();
}

}  // namespace

const ImportedCamera* CameraFile::Find(std::string_view image_file_name) const {
  for (const ImportedCamera& camera : cameras) {
    if (camera.name == image_file_name) return &camera;
  }
  const std::string stem = Stem(image_file_name);
  for (const ImportedCamera& camera : cameras) {
    if (Stem(camera.name) == stem) return &camera;
  }
  return nullptr;
}

Expected<CameraFile> ParseCameraFile(std::string_view text, std::string origin) {
  CameraFile file;
  file.origin = std::move(origin);
  const auto bad = [&](int line, const std::string& what) {
    return MakeError(ErrorCode::kBadInput, fmt::format("{}:{}: {}", file.origin, line, what));
  };
  int expected_count = -1;
  int count_line = 0;
  int numbers_per_line = 0;
  bool first_content_line = true;
  std::set<std::string, std::less<>> names;
  int line_number = 0;
  std::size_t pos = 0;
  while (pos <= text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_number;
    if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) {
      line = line.substr(0, hash);
    }
    const std::vector<std::string_view> tokens = Tokens(line);
    if (tokens.empty()) continue;
    if (first_content_line) {
      first_content_line = false;
      int count = 0;
      if (tokens.size() == 1 && ParseCount(tokens[0], &count)) {
        expected_count = count;
        count_line = line_number;
        continue;
      }
    }
    const int numbers = static_cast<int>(tokens.size()) - 1;
    if (numbers != kMiddleburyNumbers && numbers != kProjectionNumbers) {
      return bad(line_number,
                 fmt::format("expected a name and {} numbers (Middlebury: K, R, t) or {} numbers "
                             "(a 3x4 projection matrix), found {} field(s)",
                             kMiddleburyNumbers, kProjectionNumbers, tokens.size()));
    }
    if (numbers_per_line == 0) {
      numbers_per_line = numbers;
      file.format = numbers == kMiddleburyNumbers ? CameraFileFormat::kMiddlebury
                                                  : CameraFileFormat::kProjection;
    } else if (numbers != numbers_per_line) {
      return bad(line_number, fmt::format("{} numbers, but the lines above have {} (one format "
                                          "per file)",
                                          numbers, numbers_per_line));
    }
    std::vector<double> values(static_cast<std::size_t>(numbers));
    for (int i = 0; i < numbers; ++i) {
      if (!ParseDouble(tokens[static_cast<std::size_t>(i) + 1], &values[i])) {
        return bad(line_number, fmt::format("field {} (\"{}\") is not a finite number", i + 2,
                                            tokens[static_cast<std::size_t>(i) + 1]));
      }
    }
    ImportedCamera camera;
    camera.name = std::string(tokens[0]);
    camera.line = line_number;
    if (numbers == kMiddleburyNumbers) {
      Eigen::Matrix3d k;
      Eigen::Matrix3d r;
      for (int i = 0; i < 9; ++i) {
        k(i / 3, i % 3) = values[i];
        r(i / 3, i % 3) = values[9 + i];
      }
      const Eigen::Vector3d t(values[18], values[19], values[20]);
      camera.pixel_from_object.leftCols<3>() = k * r;
      camera.pixel_from_object.col(3) = k * t;
    } else {
      for (int i = 0; i < 12; ++i) camera.pixel_from_object(i / 4, i % 4) = values[i];
    }
    const Eigen::Matrix3d m = camera.pixel_from_object.leftCols<3>();
    const bool affine = m.row(2).isZero(0.0) && camera.pixel_from_object(2, 3) != 0.0;
    const double scale = m.cwiseAbs().maxCoeff();
    const bool usable = affine ? m.row(0).cross(m.row(1)).norm() > 1e-12 * scale * scale
                               : std::abs(m.determinant()) > 1e-12 * scale * scale * scale;
    if (!usable) {
      return bad(line_number, fmt::format("the camera of \"{}\" is degenerate (its 3x3 part is "
                                          "singular): not a pinhole or affine projection",
                                          camera.name));
    }
    if (!names.insert(camera.name).second) {
      return bad(line_number, fmt::format("\"{}\" is given twice", camera.name));
    }
    file.cameras.push_back(std::move(camera));
  }
  if (file.cameras.empty()) {
    return MakeError(ErrorCode::kBadInput, fmt::format("{}: no camera in the file", file.origin));
  }
  if (expected_count >= 0 && expected_count != static_cast<int>(file.cameras.size())) {
    return bad(count_line, fmt::format("the file says {} view(s) but holds {}", expected_count,
                                       file.cameras.size()));
  }
  return file;
}

Expected<CameraFile> ReadCameraFile(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    return MakeError(ErrorCode::kNotFound, fmt::format("{}: camera file not found", path.string()));
  }
  // A line is at most a few hundred bytes: 64 MB holds far more views than any data set. A
  // device or FIFO is refused, never read.
  auto text = ReadRegularFile(path, std::uintmax_t{64} << 20);
  if (!text) {
    return MakeError(text.error().code,
                     fmt::format("{} (expected a camera file)", text.error().message));
  }
  return ParseCameraFile(*text, path.string());
}

Expected<std::vector<View>> ViewsForImages(const CameraFile& file,
                                           const std::vector<std::string>& image_file_names,
                                           int width_px, int height_px) {
  std::vector<View> views;
  views.reserve(image_file_names.size());
  for (const std::string& name : image_file_names) {
    const ImportedCamera* camera = file.Find(name);
    if (camera == nullptr) {
      return MakeError(
          ErrorCode::kBadInput,
          fmt::format("{}: no camera for this image in {} ({} camera(s) for {} "
                      "image(s))",
                      name, file.origin, file.cameras.size(), image_file_names.size()));
    }
    View view;
    view.pixel_from_object = camera->pixel_from_object;
    view.width_px = width_px;
    view.height_px = height_px;
    views.push_back(view);
  }
  return views;
}

ProjectionCheck CheckProjection(const Matrix34d& pixel_from_object) {
  ProjectionCheck check;
  const Eigen::Matrix3d m = pixel_from_object.leftCols<3>();
  if (m.row(2).isZero(0.0)) {
    check.affine = true;
    check.oddities = "affine (orthographic) camera";
    return check;
  }
  // RQ by QR of the row-reversed transpose: flip * M = U^T Q^T, so M = (flip U^T flip)(flip Q^T).
  Eigen::Matrix3d flip = Eigen::Matrix3d::Zero();
  flip(0, 2) = flip(1, 1) = flip(2, 0) = 1.0;
  const Eigen::HouseholderQR<Eigen::Matrix3d> qr((flip * m).transpose());
  const Eigen::Matrix3d u = qr.matrixQR().triangularView<Eigen::Upper>();
  const Eigen::Matrix3d q = qr.householderQ();
  Eigen::Matrix3d k = flip * u.transpose() * flip;
  Eigen::Matrix3d r = flip * q.transpose();
  for (int i = 0; i < 3; ++i) {
    if (k(i, i) < 0.0) {
      k.col(i) *= -1.0;
      r.row(i) *= -1.0;
    }
  }
  const double scale = k(2, 2);
  check.K = k / scale;
  check.R = r;
  check.t = k.inverse() * pixel_from_object.col(3);
  check.mirrored = r.determinant() < 0.0;
  check.skew = check.K(0, 1) / check.K(0, 0);
  check.aspect = check.K(1, 1) / check.K(0, 0);
  std::vector<std::string> odd;
  if (std::abs(check.skew) > 1e-3) odd.push_back(fmt::format("skew {:.4f}", check.skew));
  if (std::abs(check.aspect - 1.0) > 1e-3) {
    odd.push_back(fmt::format("pixel aspect {:.4f}", check.aspect));
  }
  if (check.mirrored) odd.push_back("mirrored (left-handed) frame");
  for (std::size_t i = 0; i < odd.size(); ++i) {
    check.oddities += (i == 0 ? "" : ", ") + odd[i];
  }
  return check;
}

}  // namespace revolve::reconstruct
