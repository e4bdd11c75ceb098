// Mesh files: writers (PLY, OBJ + MTL + PNG, STL, glTF binary, VRML 2.0) and the readers tests
// use to check them.
//
// Every writer builds each file under a temporary name in the target directory
// (".<name>.tmp-XXXXXX"), fsyncs it, renames it over its path and fsyncs the directory: a crash
// leaves either the old file or the complete new one, never a half-written model, and a failed
// write leaves no temporary file behind. Errors name the file.
//
// Units and axes: every format holds the object frame (base/rig.h: millimetres, z up along the
// turntable's axis, origin on the plate) as it is, except glTF and VRML, whose viewers assume
// metres and y up: there the points are still millimetres and a node transform (scale 0.001,
// rotation -90 deg about x) shows the object upright at its true size.
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

// Text formats (OBJ, VRML) write millimetres with 4 decimals (0.1 um), uvs with 6
// and colours in [0, 1] with 4 (the 8-bit values read back exactly); trailing zeros dropped.
//
// Wavefront OBJ at `path` with its material library beside it (`path` with extension .mtl) and,
// when the mesh has a texture, the atlas as a PNG (extension .png). OBJ: "mtllib", "v x y z"
// (plus "r g b" in [0, 1] when the mesh has colours, the common extension), "vt u v" with v
// measured from the BOTTOM of the image (OBJ's convention: v = 1 - Mesh's v), "usemtl revolve",
// and "f a/ta b/tb c/tc" (1-based; "f a b c" without texture). No normals: readers smooth-shade
// the welded vertices themselves. MTL: one material "revolve"
// (Kd 1 1 1 and map_Kd with a texture, Kd 0.8 0.8 0.8 without).
Expected<void> WriteObj(const Mesh& mesh, const std::filesystem::path& path);

// Binary STL: an 80-byte header, the triangle count, and per triangle its unit normal (zero for a
// degenerate triangle) and 3 vertices (float, counter-clockwise seen from outside), attribute 0.
// Millimetres, z up; no colour.
Expected<void> WriteStl(const Mesh& mesh, const std::filesystem::path& path);

// glTF 2.0 binary (.glb): one scene, one node (scale 0.001, rotation -90 deg about x: y up,
// metres) holding one mesh with one indexed triangle primitive: POSITION (float, mm), NORMAL
// (unit, area-weighted over the faces around each vertex), TEXCOORD_0 and an embedded PNG base
// colour texture when the mesh has a texture (vertices are split where a vertex carries several
// uvs), else COLOR_0 (unsigned byte, normalized, RGBA with alpha 255) when it has colours;
// indices unsigned int; one material (metallic 0, roughness 1, single-sided).
Expected<void> WriteGlb(const Mesh& mesh, const std::filesystem::path& path);

// The number of vertices WriteGlb writes: one per distinct (vertex, uv) pair of the faces when
// the mesh has a texture, else vertices.size().
std::size_t GlbVertexCount(const Mesh& mesh);

// VRML 2.0 (the thesis's output, section 2.4 / Appendix B): one Shape with a Material and an
// IndexedFaceSet (solid TRUE, coord Coordinate, coordIndex, and colorPerVertex TRUE with a Color
// node when the mesh has colours), and a NavigationInfo. The lists hold one entry per line, not
// indented: point "x y z,", color "r g b,", coordIndex "a b c -1,". The Shape sits in a
// Transform (scale 0.001, rotation -90 deg about x) so VRML viewers, which are metres and y-up,
// show the object upright at its true size; the point coordinates themselves are the object
// frame's millimetres, exactly as in the mesh.
Expected<void> WriteVrml(const Mesh& mesh, const std::filesystem::path& path);

// The formats WriteModel knows: "ply", "obj", "stl", "glb", "wrl".
bool IsModelFormat(std::string_view format);
inline constexpr std::string_view kModelFormats[] = {"ply", "obj", "stl", "glb", "wrl"};

// Writes `dir`/`basename`.<format> for each format in kModelFormats (duplicates written once;
// "obj" also writes .mtl and, with a texture, .png; "wrl" of a mesh with a view-dependent texture
// is WriteTexturedVrml's (reconstruct/meridian/meridian_vrml.h: <basename>_texNN.jpg beside it,
// millimetres scaled to metres), else WriteVrml's); returns the paths written, in order. `dir`
// must exist. The texture is PNG-encoded once for OBJ and glTF. The files are put in place
// together once all are written (ModelWriter, reconstruct/io/model_writer.h, which also writes
// them while the mesh is still being made). Errors: bad_input for an unknown format (nothing
// written), io naming the file otherwise (no file of this model put in place).
Expected<std::vector<std::filesystem::path>> WriteModel(const Mesh& mesh,
                                                        const std::filesystem::path& dir,
                                                        std::string_view basename,
                                                        const std::vector<std::string>& formats);

// PLY, binary little-endian or ASCII: vertex x, y, z (any numeric type), optional red, green,
// blue (uchar), faces from "vertex_indices" or "vertex_index" lists (polygons are fanned into
// triangles). Other elements and properties are skipped. Errors: not_found, bad_input naming the
// file and what is wrong.
Expected<Mesh> ReadPly(const std::filesystem::path& path);

// OBJ as WriteObj writes it: "v" (with optional colours), "vt", and "f" with v, v/vt, v/vt/vn
// or v//vn corners (polygons fanned; negative indices count from the end); the texture is not
// loaded. uvs are returned in Mesh's convention (v from the top). Other lines are skipped.
Expected<Mesh> ReadObj(const std::filesystem::path& path);

// Binary STL: vertices are not welded (3 per triangle).
Expected<Mesh> ReadStl(const std::filesystem::path& path);

// The IndexedFaceSet of a VRML 2.0 file as WriteVrml writes it: Coordinate points, coordIndex
// (polygons fanned), and per-vertex Color when present. Coordinates are returned as written
// (the Transform is not applied).
Expected<Mesh> ReadVrml(const std::filesystem::path& path);

}  // namespace revolve::reconstruct
