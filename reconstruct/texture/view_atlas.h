// A view-dependent texture (Mesh::view_texture: each face from one view's image) packed into one
// texture atlas (Mesh::texture, uvs, uv_faces), for the formats that hold a single image per
// material (OBJ + MTL, glTF).
//
// Each image contributes the rectangle its faces' uvs span, plus a 2-pixel margin (clipped to the
// image); faces without an image share a small mid-grey patch (0.8 grey, the VRML material's
// colour). Rectangles are shelf-packed, tallest first, into an atlas whose width is a power of two
// of at most `atlas_size_px`; when they do not fit the rectangles are scaled down (by 0.9 until
// they do). At scale 1 the atlas holds the frames' own pixels, untouched, and every corner
// samples the very pixel its view-texture uv names. Corners at the same atlas point share one uv.
#pragma once

#include "base/error.h"
#include "reconstruct/mesh.h"

namespace revolve::reconstruct {

// Fills mesh->texture, uvs and uv_faces from mesh->view_texture (replacing any atlas). Errors:
// bad_input when the mesh has no view-dependent texture, an image is not CV_8UC3, a uv index is
// out of range, or atlas_size_px is outside 64..16384; the mesh is then unchanged.
Expected<void> AtlasFromViewTexture(Mesh* mesh, int atlas_size_px);

}  // namespace revolve::reconstruct
