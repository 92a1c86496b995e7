#pragma once
// Triangle-mesh files: PLY, OBJ, OFF, STL, VTP.
//
// Reading: the format comes from the magic bytes ("ply", "OFF", "<?xml"/"<VTKFile", binary STL
// by its size rule 84 + 50·n, ASCII STL "solid"), else from the extension (.obj). PLY, STL and
// VTP go through VTK's readers (single precision for PLY/STL, as VTK stores them); OFF and OBJ
// are read here, in double precision (OBJ: `v` and `f` lines, corners v, v/vt, v//vn or
// v/vt/vn with texture and normal indices ignored, negative indices relative to the last
// vertex read; every other statement skipped). Polygons with more than three corners are split
// into a fan of triangles. Any problem gives an InputError naming the file (OBJ: and the line).
// Coordinates must be finite and within ±kMaxMeshCoordinate.
// Writing: the format comes from the extension. VTP (VTK's XML writer, double precision) and
// PLY (written here so that per-face scalars can be stored as face properties, binary little
// endian, double coordinates) carry per-face scalars; OBJ, STL (VTK writers) and OFF do not.
// Provenance: one line of text (octshape writes JSON: version, command, the inputs' SHA-256,
// every option) stored as a PLY header comment and an OFF/OBJ comment line, each starting
// with "octshape_provenance ", and as the VTP field-data string array "octshape_provenance";
// binary STL has no room for it (an 80-byte header). read_mesh returns it from PLY, OFF, OBJ
// and VTP.

#include <filesystem>
#include <iosfwd>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "octshape/mesh/mesh.h"

namespace octshape::io {

enum class MeshFormat { kPly, kObj, kOff, kStl, kVtp };

// The largest coordinate magnitude a mesh file may hold. Below it, the squared areas of faces
// (fourth powers of coordinate differences, ≤ 16e200) and triple products stay far inside the
// double range (1.8e308), so no geometry a denoiser or metric computes can overflow; a mesh in
// any physical unit is many orders of magnitude inside it.
inline constexpr double kMaxMeshCoordinate = 1e50;

struct MeshData {
    mesh::Vertices V;        // #V×3
    mesh::Faces F;           // #F×3 (polygons fan-triangulated)
    std::string provenance;  // as written by octshape (PLY, OFF, OBJ, VTP), else empty
};

// One named per-face scalar (#F values), e.g. {"feature_strength", s_f}.
using FaceScalars = std::vector<std::pair<std::string, Eigen::VectorXd>>;

// The format named by a file's extension (case-insensitive: .ply .obj .off .stl .vtp).
// Throws UsageError for any other extension.
[[nodiscard]] MeshFormat mesh_format_from_extension(const std::filesystem::path& path);

// Reads a mesh file. Throws InputError (missing, unreadable, corrupt, unsupported; with the
// path) — also for faces that index missing vertices, non-finite coordinates or no triangle.
[[nodiscard]] MeshData read_mesh(const std::filesystem::path& path);

// Reads OFF from a stream (`name` for messages). Throws InputError with the byte offset.
[[nodiscard]] MeshData read_off(std::istream& in, const std::string& name);

// Reads OBJ from a stream (`name` for messages). Throws InputError with the line and byte
// offset. The provenance comment written by write_mesh is returned.
[[nodiscard]] MeshData read_obj(std::istream& in, const std::string& name);

// Writes (V, F) and, where the format holds them, the per-face scalars (each must have #F
// values, else UsageError). The file is written to a temporary name beside `path` and renamed,
// so a failed write never leaves a partial file. Throws OutputError if it cannot be written.
// `provenance` (see above) must be one line (UsageError otherwise).
void write_mesh(const std::filesystem::path& path,
                const mesh::Vertices& V,
                const mesh::Faces& F,
                const FaceScalars& scalars = {},
                const std::string& provenance = {});

// OFF text to a stream (full double precision), with the provenance comment if not empty.
void write_off(std::ostream& out, const mesh::Vertices& V, const mesh::Faces& F,
               const std::string& provenance = {});

// Per-vertex scalars (#V values each), e.g. {"sd_mm", sd}: written as VTP point data or PLY
// vertex properties (the only formats that carry them; others give a UsageError). Same
// temporary-name-and-rename and errors as write_mesh.
using VertexScalars = std::vector<std::pair<std::string, Eigen::VectorXd>>;
void write_mesh_vertex_scalars(const std::filesystem::path& path,
                               const mesh::Vertices& V,
                               const mesh::Faces& F,
                               const VertexScalars& scalars,
                               const std::string& provenance = {});

}  // namespace octshape::io
