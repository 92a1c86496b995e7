// write_mesh_vertex_scalars (mesh_io.h): meshes with per-vertex scalars, VTP or PLY.

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <system_error>

#include <vtkCellArray.h>
#include <vtkDoubleArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkXMLPolyDataWriter.h>

#include "octshape/io/error.h"
#include "octshape/io/mesh_io.h"

namespace octshape::io {
namespace {

namespace fs = std::filesystem;

template <class T>
void put_le(std::ostream& out, T value) {
    std::array<char, sizeof(T)> bytes{};
    std::memcpy(bytes.data(), &value, sizeof(T));
    if constexpr (std::endian::native == std::endian::big) std::reverse(bytes.begin(), bytes.end());
    out.write(bytes.data(), sizeof(T));
}

void write_ply(std::ostream& out,
               const mesh::Vertices& V,
               const mesh::Faces& F,
               const VertexScalars& scalars) {
    out << "ply\nformat binary_little_endian 1.0\ncomment written by octshape\n"
        << "element vertex " << V.rows() << "\nproperty double x\nproperty double y\n"
        << "property double z\n";
    for (const auto& s : scalars) out << "property double " << s.first << '\n';
    out << "element face " << F.rows() << "\nproperty list uchar int vertex_indices\n"
        << "end_header\n";
    for (Eigen::Index i = 0; i < V.rows(); ++i) {
        for (int k = 0; k < 3; ++k) put_le<double>(out, V(i, k));
        for (const auto& s : scalars) put_le<double>(out, s.second(i));
    }
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        put_le<std::uint8_t>(out, 3);
        for (int k = 0; k < 3; ++k) put_le<std::int32_t>(out, F(f, k));
    }
}

void write_vtp(const fs::path& tmp,
               const fs::path& path,
               const mesh::Vertices& V,
               const mesh::Faces& F,
               const VertexScalars& scalars) {
    vtkNew<vtkPoints> points;
    points->SetDataTypeToDouble();
    points->SetNumberOfPoints(V.rows());
    for (Eigen::Index i = 0; i < V.rows(); ++i) points->SetPoint(i, V(i, 0), V(i, 1), V(i, 2));
    vtkNew<vtkCellArray> polys;
    polys->AllocateExact(F.rows(), F.rows() * 3);
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        const std::array<vtkIdType, 3> ids{F(f, 0), F(f, 1), F(f, 2)};
        polys->InsertNextCell(3, ids.data());
    }
    vtkNew<vtkPolyData> poly;
    poly->SetPoints(points);
    poly->SetPolys(polys);
    for (const auto& [name, values] : scalars) {
        vtkNew<vtkDoubleArray> array;
        array->SetName(name.c_str());
        array->SetNumberOfValues(values.size());
        for (Eigen::Index i = 0; i < values.size(); ++i) array->SetValue(i, values(i));
        poly->GetPointData()->AddArray(array);
    }
    vtkNew<vtkXMLPolyDataWriter> writer;
    writer->SetFileName(tmp.string().c_str());
    writer->SetInputData(poly);
    if (writer->Write() != 1) throw OutputError(path.string(), "VTK writer failed");
}

}  // namespace

void write_mesh_vertex_scalars(const fs::path& path,
                               const mesh::Vertices& V,
                               const mesh::Faces& F,
                               const VertexScalars& scalars) {
    const MeshFormat format = mesh_format_from_extension(path);
    if (format != MeshFormat::kVtp && format != MeshFormat::kPly) {
        throw UsageError(path.string() + ": per-vertex scalars need .vtp or .ply");
    }
    for (const auto& [name, values] : scalars) {
        if (values.size() != V.rows()) {
            throw UsageError("vertex scalar '" + name + "' has " +
                             std::to_string(values.size()) + " values for " +
                             std::to_string(V.rows()) + " vertices");
        }
        if (name.empty() || std::any_of(name.begin(), name.end(), [](unsigned char c) {
                return std::isspace(c) != 0;
            })) {
            throw UsageError("vertex scalar name '" + name + "' must be one word");
        }
    }
    const fs::path tmp = path.string() + ".partial";
    try {
        if (format == MeshFormat::kPly) {
            std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
            if (!out) throw OutputError(path.string(), std::strerror(errno));
            write_ply(out, V, F, scalars);
            out.close();
            if (!out) throw OutputError(path.string(), "write failed");
        } else {
            write_vtp(tmp, path, V, F, scalars);
        }
        std::error_code ec;
        fs::rename(tmp, path, ec);
        if (ec) throw OutputError(path.string(), ec.message());
    } catch (...) {
        std::error_code ec;
        fs::remove(tmp, ec);
        throw;
    }
}

}  // namespace octshape::io
