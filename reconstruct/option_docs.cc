// The descriptions of [reconstruct] for the configuration reference
// (docs/configuration.md, made by `revolve check-config --reference`). The types, defaults and
// ranges come from the parser itself; a key it reads with no description here fails the test
// config_reference.
#include "reconstruct/reconstructor.h"

namespace revolve::reconstruct {
namespace {

constexpr config::TableDoc kTables[] = {
    {"reconstruct", ""},
};

constexpr config::KeyDoc kKeys[] = {
    {"reconstruct", "method", "",
     "the visual hull, or the thesis's meridian method ([methods](reconstruction.md#two-methods))"},
    {"reconstruct", "resolution", "voxels",
     "hull: voxels along the longest side of the carving volume (cubic voxels)"},
    {"reconstruct", "volume_radius_mm", "mm",
     "hull: the carving volume, a box around a cylinder of this radius on the plate…"},
    {"reconstruct", "volume_height_mm", "mm", "…and this height; it must contain the object"},
    {"reconstruct", "formats", "", "model files written to `model/`", "", "",
     "a non-empty list of `ply`, `obj`, `stl`, `glb`, `wrl` (duplicates dropped)"},
    {"reconstruct", "texture", "",
     "write a texture atlas for obj and glb (vertex colours are written either way, whenever "
     "frames are available)"},
    {"reconstruct", "texture_size_px", "px",
     "largest side of the texture atlas; charts keep one texel per frame pixel when "
     "they fit, else shrink together"},
    {"reconstruct", "flat_bottom", "",
     "cut the model flat at the plate (z = 0) and close it with a flat face, so it stands and "
     "prints"},
    {"reconstruct", "meridian_row_step_px", "px",
     "meridian: a feature point every this many image rows (the thesis's h_RANGE)"},
    {"reconstruct", "meridian_both_sides", "",
     "meridian: also take the rightmost pixel as the view at θ + 180°"},
};

}  // namespace

config::OptionDocs ReferenceDocs() { return {kTables, kKeys}; }

}  // namespace revolve::reconstruct
