#include "base/image_files.h"

#include <algorithm>
#include <cctype>
#include <map>
#include <set>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

namespace revolve {

bool IsImageFile(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".png" || ext == ".tif" || ext == ".tiff" || ext == ".jpg" || ext == ".jpeg" ||
         ext == ".bmp" || ext == ".pgm" || ext == ".ppm";
}

bool NaturalLess(std::string_view a, std::string_view b) {
  std::size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    if (std::isdigit(static_cast<unsigned char>(a[i])) &&
        std::isdigit(static_cast<unsigned char>(b[j]))) {
      std::size_t i_end = i, j_end = j;
      while (i_end < a.size() && std::isdigit(static_cast<unsigned char>(a[i_end]))) ++i_end;
      while (j_end < b.size() && std::isdigit(static_cast<unsigned char>(b[j_end]))) ++j_end;
      // Compare the numbers without leading zeros: longer is larger, then digit by digit.
      std::string_view x = a.substr(i, i_end - i), y = b.substr(j, j_end - j);
      x.remove_prefix(std::min(x.find_first_not_of('0'), x.size()));
      y.remove_prefix(std::min(y.find_first_not_of('0'), y.size()));
      if (x.size() != y.size()) return x.size() < y.size();
      if (x != y) return x < y;
      i = i_end;
      j = j_end;
      continue;
    }
    if (a[i] != b[j]) return static_cast<unsigned char>(a[i]) < static_cast<unsigned char>(b[j]);
    ++i;
    ++j;
  }
  if ((a.size() - i) != (b.size() - j)) return a.size() - i < b.size() - j;
  return a < b;  // equal up to leading zeros: any fixed tie-break
}

Expected<std::vector<std::filesystem::path>> ListImageFiles(const std::filesystem::path& dir) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) {
    return MakeError(ErrorCode::kNotFound, fmt::format("{}: no such folder", dir.string()));
  }
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    if (!IsImageFile(entry.path())) continue;
    std::error_code entry_ec;
    if (entry.is_symlink(entry_ec) && !entry.exists(entry_ec)) {
      return MakeError(ErrorCode::kNotFound,
                       fmt::format("{}: a dangling symbolic link (its target {} does not exist); "
                                   "fix or remove it",
                                   entry.path().string(),
                                   std::filesystem::read_symlink(entry.path(), entry_ec).string()));
    }
    if (entry.is_regular_file(entry_ec)) files.push_back(entry.path());
  }
  if (ec) {
    return MakeError(ErrorCode::kIo,
                     fmt::format("{}: cannot list the folder: {}", dir.string(), ec.message()));
  }
  std::sort(files.begin(), files.end(), [](const auto& x, const auto& y) {
    return NaturalLess(x.filename().string(), y.filename().string());
  });
  return files;
}

std::string WhatAFolderHoldsInstead(const std::filesystem::path& dir) {
  std::error_code ec;
  std::map<std::string, int> by_extension;                   // regular files, lower-case extension
  std::vector<std::pair<std::string, std::size_t>> folders;  // with images in them
  int entries = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    ++entries;
    std::error_code entry_ec;
    if (entry.is_directory(entry_ec)) {
      Expected<std::vector<std::filesystem::path>> inside = ListImageFiles(entry.path());
      if (inside && !inside->empty()) {
        folders.emplace_back(entry.path().filename().string(), inside->size());
      }
      continue;
    }
    if (!entry.is_regular_file(entry_ec)) continue;
    std::string extension = entry.path().extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (!extension.empty()) ++by_extension[extension];
  }
  if (ec) return {};
  if (entries == 0) return "it is empty";
  // Photo formats cameras, phones and raw converters write that the readers here do not.
  static const std::set<std::string> kPhotoFormats = {
      ".heic", ".heif", ".avif", ".webp", ".jxl", ".gif", ".dng", ".cr2", ".cr3", ".nef",
      ".arw",  ".orf",  ".rw2",  ".raf",  ".pef", ".srw", ".raw", ".jp2", ".exr", ".hdr"};
  std::vector<std::string> photos;
  for (const auto& [extension, count] : by_extension) {
    if (kPhotoFormats.contains(extension)) {
      photos.push_back(fmt::format("{} {} file{}", count, extension, count == 1 ? "" : "s"));
    }
  }
  if (!photos.empty()) {
    return fmt::format(
        "it holds {}, a format revolve does not read: convert them to JPEG, PNG or TIFF first",
        fmt::join(photos, " and "));
  }
  if (!folders.empty()) {
    std::sort(folders.begin(), folders.end());
    const auto& [name, count] = folders.front();
    return fmt::format(
        "its folder {}/ holds {} image{}{}: pass that folder", name, count, count == 1 ? "" : "s",
        folders.size() > 1 ? fmt::format(" ({} more folders hold images)", folders.size() - 1)
                           : std::string());
  }
  return {};
}

}  // namespace revolve
