#pragma once
// Private to octshape_io: the pieces the mesh and point-set readers and writers share (VTK
// reading with its errors caught, the polydata and binary-PLY writers, extension handling).

#include <vtkNew.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <filesystem>
#include <new>
#include <stdexcept>
#include <ostream>
#include <string>

#include "octshape/error.h"
#include "octshape/io/mesh_io.h"
#include "octshape/io/vtk_errors.h"

namespace octshape::io::detail {

// The extension of `path`, lower case, with its dot (".ply").
[[nodiscard]] std::string lower_extension(const std::filesystem::path& path);

// Runs a VTK polydata reader on `path`; any error or warning it reports is an InputError
// (corrupt) naming the file. The output may still be empty: callers check what they need.
// PLY and VTP headers declare element counts: refuses (InputError, corrupt) counts the file
// cannot hold — a PLY element needs at least its binary property sizes (ASCII: 2 bytes a
// property) per item; a VTP point or cell at least 1 byte, or 1/10000 of one when compressed
// (zlib stops near 1:1032) — before a reader allocates for them. Other files: no check.
void check_declared_counts(const std::filesystem::path& path);

template <class Reader>
vtkSmartPointer<vtkPolyData> read_polydata(const std::filesystem::path& path) {
    check_declared_counts(path);
    vtkNew<Reader> reader;
    reader->SetFileName(path.string().c_str());
    try {
        run_vtk(
            reader, [&] { reader->Update(); },
            [&](const std::string& m) {
                return InputError::corrupt(path.string(), "VTK reader: " + m);
            },
            VtkReport::kErrorsAndWarnings);
    } catch (const std::bad_alloc&) {
        throw InputError::corrupt(path.string(), "its declared sizes need more memory than there is");
    } catch (const std::length_error&) {
        throw InputError::corrupt(path.string(), "its declared sizes need more memory than there is");
    }
    return reader->GetOutput();
}

// Runs a VTK writer on `poly`, writing the file `tmp`; errors are OutputErrors naming `path`.
template <class Writer>
void write_polydata(Writer* writer, vtkPolyData* poly, const std::string& tmp,
                    const std::string& path) {
    writer->SetFileName(tmp.c_str());
    writer->SetInputData(poly);
    int written = 0;
    const std::string message = vtk_first_error(writer, [&] { written = writer->Write(); });
    if (written != 1 || !message.empty()) throw OutputError(path, "VTK writer: " + message);
}

// (V, F) as VTK polydata in double precision, with point and cell data arrays.
[[nodiscard]] vtkSmartPointer<vtkPolyData> to_polydata(const mesh::Vertices& V,
                                                       const mesh::Faces& F,
                                                       const VertexScalars& vertex_scalars,
                                                       const FaceScalars& face_scalars);

template <class T>
void put_le(std::ostream& out, T value) {
    std::array<char, sizeof(T)> bytes{};
    std::memcpy(bytes.data(), &value, sizeof(T));
    if constexpr (std::endian::native == std::endian::big) std::reverse(bytes.begin(), bytes.end());
    out.write(bytes.data(), sizeof(T));
}

// Binary little-endian PLY with double coordinates; vertex scalars as vertex properties, face
// scalars as face properties, the provenance (if not empty) as a header comment. Empty F
// writes a point set.
void write_ply(std::ostream& out,
               const mesh::Vertices& V,
               const mesh::Faces& F,
               const VertexScalars& vertex_scalars,
               const FaceScalars& face_scalars,
               const std::string& provenance = {});

// The comment keyword of the provenance line (PLY, OFF, OBJ) and the VTP array's name.
inline constexpr const char* kProvenanceKey = "octshape_provenance";

}  // namespace octshape::io::detail
