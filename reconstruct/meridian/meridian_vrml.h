// VRML 2.0 with view-dependent texture, as the thesis wrote it (2.4, Appendix B: Shape,
// Appearance with Material and ImageTexture, IndexedFaceSet with Coordinate, TextureCoordinate,
// coordIndex, texCoordIndex; NavigationInfo), for a mesh with a view-dependent texture
// (Mesh::view_texture, made by the meridian method). WriteModel (reconstruct/io/mesh_io.h)
// writes "wrl" with it for such a mesh, so every path (revolve scan, revolve reconstruct SCAN_DIR
// and --images) writes the same textured VRML.
//
// Layout of `path` (e.g. model.wrl) and its images:
//   #VRML V2.0 utf8
//   Transform { scale s s s  rotation 1 0 0 -1.5708  children [
//     Shape { appearance Appearance { material Material { diffuseColor ... }
//                                    texture ImageTexture { url "model_tex00.jpg" } }
//             geometry IndexedFaceSet { solid TRUE
//               coord DEF model_coords Coordinate { point [ x y z, ... ] }
//               coordIndex [ a, b, c, -1, ... ]
//               texCoord TextureCoordinate { point [ s t, ... ] }
//               texCoordIndex [ i, j, k, -1, ... ] } }
//     Shape { ... coord USE model_coords ... }      one Shape per texture image (the thesis wrote
//     ...                                           one per view), one untextured Shape last
//   ] }
//   NavigationInfo { type "EXAMINE" }
// The Transform turns the object frame (z up) into VRML's y-up frame and scales its units to
// metres (`metres_per_unit`: 0.001 for millimetres; thesis mode's pixels are unscaled, 1 gives a
// 500 px object 500 m tall: viewers fit it to the window anyway). Point coordinates are the
// mesh's, unchanged. Texture images are written as JPEG (quality 92) next to the .wrl, named
// <stem>_tex<NN>.jpg, and referenced by relative URL.
//
// Every file is written atomically (temporary name, fsync, rename: base/atomic_file.h); images
// first, the .wrl last, so a .wrl never points at a missing image.
#pragma once

#include <filesystem>
#include <vector>

#include "base/error.h"
#include "reconstruct/mesh.h"

namespace revolve::reconstruct {

// Writes the mesh (see the file comment) and returns the files written (.wrl last). A mesh
// without a view-dependent texture is written as one untextured Shape. Errors: io / not_found
// naming the file.
Expected<std::vector<std::filesystem::path>> WriteTexturedVrml(const Mesh& mesh,
                                                               const std::filesystem::path& path,
                                                               double metres_per_unit);

// Texture images named in a .wrl written by WriteTexturedVrml: the `url` strings, in order.
// Errors: not_found / bad_input naming the file.
Expected<std::vector<std::string>> ReadVrmlTextureUrls(const std::filesystem::path& path);

}  // namespace revolve::reconstruct
