#include "octshape/io/pointset_io.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <string_view>
#include <system_error>
#include <vector>

#include <vtkCommand.h>
#include <vtkNew.h>
#include <vtkPLYReader.h>
#include <vtkPolyData.h>

#include "mesh_io_detail.h"
#include "octshape/io/atomic_file.h"
#include "octshape/error.h"

namespace octshape::io {
namespace {

namespace fs = std::filesystem;

mesh::Vertices to_vertices(const std::vector<std::array<double, 3>>& pts, const std::string& name) {
    if (pts.empty()) throw InputError::corrupt(name, "no point in the file");
    mesh::Vertices V(static_cast<Eigen::Index>(pts.size()), 3);
    for (std::size_t i = 0; i < pts.size(); ++i) {
        V.row(static_cast<Eigen::Index>(i)) << pts[i][0], pts[i][1], pts[i][2];
    }
    return V;
}

// Parses whitespace-separated numbers of one line; `offset` is the line's byte offset.
// Returns the first three; throws if fewer are there or one is not a number.
std::array<double, 3> three_numbers(std::string_view line, std::size_t offset,
                                    const std::string& name) {
    std::array<double, 3> xyz{};
    std::size_t pos = 0;
    for (int k = 0; k < 3; ++k) {
        while (pos < line.size() && std::isspace(static_cast<unsigned char>(line[pos]))) ++pos;
        std::size_t end = pos;
        while (end < line.size() && !std::isspace(static_cast<unsigned char>(line[end]))) ++end;
        if (end == pos) throw InputError::corrupt(name, "fewer than three coordinates", offset);
        const char* first = line.data() + pos;
        const char* last = line.data() + end;
        if (*first == '+') ++first;  // from_chars does not take a leading '+'
        double value = 0.0;
        const auto [ptr, ec] = std::from_chars(first, last, value);
        if (ec != std::errc() || ptr != last) {
            const std::string token(line.substr(pos, std::min<std::size_t>(end - pos, 32)));
            throw InputError::corrupt(name, "bad coordinate '" + token + "'", offset + pos);
        }
        if (!std::isfinite(value)) {
            throw InputError::corrupt(name, "coordinate not finite", offset + pos);
        }
        xyz[static_cast<std::size_t>(k)] = value;
        pos = end;
    }
    return xyz;
}

// Calls on_line(line, offset) for every line of `text`.
template <class OnLine>
void for_each_line(const std::string& text, const OnLine& on_line) {
    std::size_t begin = 0;
    while (begin < text.size()) {
        std::size_t end = text.find('\n', begin);
        if (end == std::string::npos) end = text.size();
        std::string_view line(text.data() + begin, end - begin);
        if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
        on_line(line, begin);
        begin = end + 1;
    }
}

std::string slurp(const fs::path& path) {
    std::error_code ec;
    const auto status = fs::status(path, ec);
    if (!fs::exists(status)) throw InputError::missing(path.string());
    if (!fs::is_regular_file(status)) throw InputError::not_regular(path.string());
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError::unreadable(path.string(), std::strerror(errno));
    std::ostringstream buffer;
    buffer << in.rdbuf();
    return buffer.str();
}

mesh::Vertices parse_xyz(const std::string& text, const std::string& name) {
    std::vector<std::array<double, 3>> pts;
    for_each_line(text, [&](std::string_view line, std::size_t offset) {
        const auto first = line.find_first_not_of(" \t");
        if (first == std::string_view::npos || line[first] == '#') return;
        pts.push_back(three_numbers(line, offset, name));
    });
    return to_vertices(pts, name);
}

mesh::Vertices parse_obj(const std::string& text, const std::string& name) {
    std::vector<std::array<double, 3>> pts;
    for_each_line(text, [&](std::string_view line, std::size_t offset) {
        const auto first = line.find_first_not_of(" \t");
        if (first == std::string_view::npos) return;
        line.remove_prefix(first);
        if (line.size() >= 2 && line[0] == 'v' && (line[1] == ' ' || line[1] == '\t')) {
            pts.push_back(three_numbers(line.substr(2), offset + first + 2, name));
        }
    });
    return to_vertices(pts, name);
}

mesh::Vertices read_ply_points(const fs::path& path) {
    const vtkSmartPointer<vtkPolyData> poly = detail::read_polydata<vtkPLYReader>(path);
    const vtkIdType n = poly != nullptr ? poly->GetNumberOfPoints() : 0;
    std::vector<std::array<double, 3>> pts(static_cast<std::size_t>(n));
    for (vtkIdType i = 0; i < n; ++i) {
        poly->GetPoint(i, pts[static_cast<std::size_t>(i)].data());
        const auto& p = pts[static_cast<std::size_t>(i)];
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
            throw InputError::corrupt(path.string(),
                                      "point " + std::to_string(i) + " is not finite");
        }
    }
    return to_vertices(pts, path.string());
}

}  // namespace

PointSetFormat point_set_format_from_extension(const fs::path& path) {
    const std::string ext = detail::lower_extension(path);
    if (ext == ".xyz" || ext == ".txt") return PointSetFormat::kXyz;
    if (ext == ".ply") return PointSetFormat::kPly;
    if (ext == ".obj") return PointSetFormat::kObj;
    throw UsageError(path.string() +
                     ": unknown point-set file extension (use .xyz, .txt, .ply or .obj)");
}

mesh::Vertices read_xyz(std::istream& in, const std::string& name) {
    std::ostringstream buffer;
    buffer << in.rdbuf();
    return parse_xyz(buffer.str(), name);
}

mesh::Vertices read_point_set(const fs::path& path) {
    const std::string name = path.string();
    std::string text = slurp(path);
    if (text.empty()) throw InputError::corrupt(name, "empty file");
    if (text.starts_with("ply")) {
        text.clear();
        return read_ply_points(path);
    }
    if (detail::lower_extension(path) == ".obj") return parse_obj(text, name);
    return parse_xyz(text, name);
}

void write_xyz(std::ostream& out, const mesh::Vertices& V, const mesh::Vertices* normals) {
    out << std::setprecision(17);
    for (Eigen::Index i = 0; i < V.rows(); ++i) {
        out << V(i, 0) << ' ' << V(i, 1) << ' ' << V(i, 2);
        if (normals != nullptr) {
            out << ' ' << (*normals)(i, 0) << ' ' << (*normals)(i, 1) << ' ' << (*normals)(i, 2);
        }
        out << '\n';
    }
}

void write_point_set(const fs::path& path, const mesh::Vertices& V, const mesh::Vertices* normals,
                     const std::string& provenance) {
    const PointSetFormat format = point_set_format_from_extension(path);
    if (normals != nullptr && normals->rows() != V.rows()) {
        throw UsageError("normals have " + std::to_string(normals->rows()) + " rows for " +
                         std::to_string(V.rows()) + " points");
    }
    if (provenance.find_first_of("\r\n") != std::string::npos) {
        throw UsageError("point-set provenance must be one line");
    }
    write_file_atomically(path.string(), [&](std::ostream& out) {
        if (!provenance.empty() && format != PointSetFormat::kPly) {
            out << "# " << detail::kProvenanceKey << ' ' << provenance << '\n';
        }
        if (format == PointSetFormat::kXyz) {
            write_xyz(out, V, normals);
        } else if (format == PointSetFormat::kObj) {
            out << "# written by octshape\n" << std::setprecision(17);
            for (Eigen::Index i = 0; i < V.rows(); ++i) {
                out << "v " << V(i, 0) << ' ' << V(i, 1) << ' ' << V(i, 2) << '\n';
            }
            for (Eigen::Index i = 0; normals != nullptr && i < V.rows(); ++i) {
                out << "vn " << (*normals)(i, 0) << ' ' << (*normals)(i, 1) << ' '
                    << (*normals)(i, 2) << '\n';
            }
        } else {
            VertexScalars normal_scalars;
            if (normals != nullptr) {
                for (int k = 0; k < 3; ++k) {
                    normal_scalars.emplace_back(std::string("n") + "xyz"[k], normals->col(k));
                }
            }
            detail::write_ply(out, V, mesh::Faces(0, 3), normal_scalars, {}, provenance);
        }
    });
}

}  // namespace octshape::io
