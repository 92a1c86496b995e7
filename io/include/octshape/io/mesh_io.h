#pragma once
// Triangle-mesh files: PLY, OBJ, OFF, STL, VTP.
//
// Reading: the format comes from the magic bytes ("ply", "OFF", "<?xml"/"<VTKFile", binary STL
// by its size rule 84 + 50·n, ASCII STL "solid"), else from the extension (.obj). PLY, OBJ,
// STL and VTP go through VTK's readers (single precision for PLY/OBJ/STL, as VTK stores them);
// OFF is read here. Polygons with more than three corners are split into a fan of triangles.
// Any problem gives an InputError naming the file.
// Writing: the format comes from the extension. VTP (VTK's XML writer, double precision) and
// PLY (written here so that per-face scalars can be stored as face properties, binary little
// endian, double coordinates) carry per-face scalars; OBJ, STL (VTK writers) and OFF do not.

#include <filesystem>
#include <iosfwd>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "octshape/mesh/mesh.h"

namespace octshape::io {

enum class MeshFormat { kPly, kObj, kOff, kStl, kVtp };

struct MeshData {
    mesh::Vertices V;  // #V×3
    mesh::Faces F;     // #F×3 (polygons fan-triangulated)
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

// Writes (V, F) and, where the format holds them, the per-face scalars (each must have #F
// values, else UsageError). The file is written to a temporary name beside `path` and renamed,
// so a failed write never leaves a partial file. Throws OutputError if it cannot be written.
void write_mesh(const std::filesystem::path& path,
                const mesh::Vertices& V,
                const mesh::Faces& F,
                const FaceScalars& scalars = {});

// OFF text to a stream (full double precision).
void write_off(std::ostream& out, const mesh::Vertices& V, const mesh::Faces& F);

// Per-vertex scalars (#V values each), e.g. {"sd_mm", sd}: written as VTP point data or PLY
// vertex properties (the only formats that carry them; others give a UsageError). Same
// temporary-name-and-rename and errors as write_mesh.
using VertexScalars = std::vector<std::pair<std::string, Eigen::VectorXd>>;
void write_mesh_vertex_scalars(const std::filesystem::path& path,
                               const mesh::Vertices& V,
                               const mesh::Faces& F,
                               const VertexScalars& scalars);

}  // namespace octshape::io
