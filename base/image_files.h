// Folders of images as the station reads them (replay camera, `revolve reconstruct --images`,
// `revolve calibrate --images`): which files are images, and their order.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "base/error.h"

namespace revolve {

// True for the image types every reader here accepts: .png .jpg .jpeg .tif .tiff .bmp .pgm .ppm,
// in any case.
bool IsImageFile(const std::filesystem::path& path);

// "Natural" order: digit runs compare as numbers, so "img2.png" < "img10.png" and
// "shoe9" < "shoe10"; otherwise byte order.
bool NaturalLess(std::string_view a, std::string_view b);

// The image files directly in `dir`, in natural order of their names; possibly none.
// Errors: not_found naming `dir` when it is not a folder, or naming an image file name that is
// a dangling symbolic link; io when it cannot be listed.
Expected<std::vector<std::filesystem::path>> ListImageFiles(const std::filesystem::path& dir);

// For a folder with no image file ListImageFiles reads: what it holds instead, as a sentence to
// follow an error ("it holds 36 .heic files, a format revolve does not read: convert them to JPEG,
// PNG or TIFF first", "its folder shots/ holds 36 images: pass that folder", "it is empty"); empty
// when none of these applies.
std::string WhatAFolderHoldsInstead(const std::filesystem::path& dir);

}  // namespace revolve
