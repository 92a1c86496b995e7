#pragma once
// Point-set files: XYZ text, PLY and OBJ (vertices only; faces, if any, are ignored).
//
// Reading: PLY by its magic bytes ("ply", any PLY VTK reads, vertices-only files included, single
// precision as VTK stores it), OBJ by the extension (.obj: the "v x y z" lines), anything else
// as XYZ text: one point per line, the first three numbers are x y z (further columns such as
// normals are ignored), blank lines and lines starting with '#' are skipped.
// Writing: the format comes from the extension (.xyz .txt .ply .obj); normals, when given,
// are written beside the points ("x y z nx ny nz" in XYZ, nx/ny/nz properties in PLY, "vn" in
// OBJ). The file is written under a temporary name and renamed.

#include <filesystem>
#include <iosfwd>
#include <string>

#include "octshape/mesh/mesh.h"

namespace octshape::io {

enum class PointSetFormat { kXyz, kPly, kObj };

// .xyz/.txt → XYZ, .ply, .obj (case-insensitive); throws UsageError for anything else.
[[nodiscard]] PointSetFormat point_set_format_from_extension(const std::filesystem::path& path);

// Reads a point set (#P×3). Throws InputError (missing, unreadable, corrupt with the byte
// offset, no point at all, non-finite coordinate).
[[nodiscard]] mesh::Vertices read_point_set(const std::filesystem::path& path);

// XYZ text from a stream (`name` for messages). Throws InputError with the byte offset.
[[nodiscard]] mesh::Vertices read_xyz(std::istream& in, const std::string& name);

// XYZ text to a stream, full double precision; `normals` (if not null) must have #P rows.
void write_xyz(std::ostream& out, const mesh::Vertices& V, const mesh::Vertices* normals = nullptr);

// Writes a point set; UsageError for a bad extension, a normals array of the wrong size or a
// provenance of more than one line, OutputError if the file cannot be written. `provenance`
// (if not empty) is written as the comment "octshape_provenance <line>": a PLY header comment,
// a "# " line first in XYZ and OBJ (both readers skip it), as for meshes (mesh_io.h).
void write_point_set(const std::filesystem::path& path,
                     const mesh::Vertices& V,
                     const mesh::Vertices* normals = nullptr,
                     const std::string& provenance = {});

}  // namespace octshape::io
