// Mesh files: writers (PLY, VRML 2.0) and the readers tests use to check them.
//
// Every writer builds the file under a temporary name in the target directory
// (".<name>.tmp-XXXXXX"), fsyncs it, renames it over `path` and fsyncs the directory: a crash
// leaves either the old file or the complete new one, never a half-written model, and a failed
// write leaves no temporary file behind. Errors name the file.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "base/error.h"
#include "reconstruct/mesh.h"

namespace revolve::reconstruct {

// Binary little-endian PLY: vertex x y z (float), plus red green blue (uchar) when the mesh has
// colours; face "list uchar int vertex_indices". Coordinates are object-frame millimetres.
Expected<void> WritePly(const Mesh& mesh, const std::filesystem::path& path);

// VRML 2.0 (the thesis's output, section 2.4 / Appendix B): one Shape with a Material and an
// IndexedFaceSet (solid TRUE, coord Coordinate, coordIndex "a, b, c, -1", and colorPerVertex TRUE
// with a Color node when the mesh has colours), and a NavigationInfo. The Shape sits in a
// Transform (scale 0.001, rotation -90 deg about x) so VRML viewers, which are metres and y-up,
// show the object upright at its true size; the point coordinates themselves are the object
// frame's millimetres, exactly as in the mesh.
Expected<void> WriteVrml(const Mesh& mesh, const std::filesystem::path& path);

// Writes `dir`/`basename`.<format> for each format ("ply", "wrl"; duplicates written once);
// returns the paths written. `dir` must exist. Errors: bad_input for an unknown format (nothing
// written), io naming the file otherwise (files written before the failing one stay).
Expected<std::vector<std::filesystem::path>> WriteModel(const Mesh& mesh,
                                                        const std::filesystem::path& dir,
                                                        std::string_view basename,
                                                        const std::vector<std::string>& formats);

// PLY, binary little-endian or ASCII: vertex x, y, z (any numeric type), optional red, green,
// blue (uchar), faces from "vertex_indices" or "vertex_index" lists (polygons are fanned into
// triangles). Other elements and properties are skipped. Errors: not_found, bad_input naming the
// file and what is wrong.
Expected<Mesh> ReadPly(const std::filesystem::path& path);

// The IndexedFaceSet of a VRML 2.0 file as WriteVrml writes it: Coordinate points, coordIndex
// (polygons fanned), and per-vertex Color when present. Coordinates are returned as written
// (the Transform is not applied).
Expected<Mesh> ReadVrml(const std::filesystem::path& path);

}  // namespace revolve::reconstruct
