#include "octshape/io/mesh_io.h"

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
#include <limits>
#include <optional>
#include <sstream>
#include <string_view>
#include <system_error>

#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkDataSetAttributes.h>
#include <vtkDoubleArray.h>
#include <vtkPointData.h>
#include <vtkNew.h>
#include <vtkOBJWriter.h>
#include <vtkPLYReader.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSTLReader.h>
#include <vtkSTLWriter.h>
#include <vtkSmartPointer.h>
#include <vtkStringArray.h>
#include <vtkFieldData.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLPolyDataWriter.h>

#include "mesh_io_detail.h"
#include "octshape/io/atomic_file.h"
#include "octshape/error.h"

namespace octshape::io {
namespace {

namespace fs = std::filesystem;

void check_input_file(const fs::path& path) {
    std::error_code ec;
    const auto status = fs::status(path, ec);
    if (!fs::exists(status)) throw InputError::missing(path.string());
    if (!fs::is_regular_file(status)) throw InputError::not_regular(path.string());
    std::ifstream probe(path, std::ios::binary);
    if (!probe) throw InputError::unreadable(path.string(), std::strerror(errno));
}

MeshData from_polydata(vtkPolyData* poly, const std::string& name) {
    MeshData out;
    if (poly == nullptr) throw InputError::corrupt(name, "no surface could be read");
    if (poly->GetNumberOfStrips() > 0) {
        throw InputError::unsupported(name, "triangle strips");
    }
    const vtkIdType n = poly->GetNumberOfPoints();
    out.V.resize(n, 3);
    for (vtkIdType i = 0; i < n; ++i) {
        std::array<double, 3> p{};
        poly->GetPoint(i, p.data());
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
            throw InputError::corrupt(name, "vertex " + std::to_string(i) + " is not finite");
        }
        if (std::max({std::abs(p[0]), std::abs(p[1]), std::abs(p[2])}) > kMaxMeshCoordinate) {
            throw InputError::corrupt(name, "vertex " + std::to_string(i) +
                                                " has a coordinate beyond ±1e50");
        }
        out.V.row(i) << p[0], p[1], p[2];
    }
    std::vector<std::array<int, 3>> triangles;
    vtkCellArray* polys = poly->GetPolys();
    if (polys != nullptr) {
        triangles.reserve(static_cast<std::size_t>(polys->GetNumberOfCells()));
        polys->InitTraversal();
        vtkIdType npts = 0;
        const vtkIdType* pts = nullptr;
        vtkIdType cell = 0;
        while (polys->GetNextCell(npts, pts) != 0) {
            if (npts < 3) {
                throw InputError::corrupt(name, "polygon " + std::to_string(cell) + " has " +
                                                    std::to_string(npts) + " corners");
            }
            for (vtkIdType k = 0; k < npts; ++k) {
                if (pts[k] < 0 || pts[k] >= n) {
                    throw InputError::corrupt(name, "polygon " + std::to_string(cell) +
                                                        " refers to a missing vertex");
                }
            }
            for (vtkIdType k = 1; k + 1 < npts; ++k) {  // fan triangulation
                triangles.push_back({static_cast<int>(pts[0]), static_cast<int>(pts[k]),
                                     static_cast<int>(pts[k + 1])});
            }
            ++cell;
        }
    }
    if (triangles.empty()) throw InputError::corrupt(name, "no triangle in the file");
    out.F.resize(static_cast<Eigen::Index>(triangles.size()), 3);
    for (std::size_t f = 0; f < triangles.size(); ++f) {
        const auto& t = triangles[f];
        out.F.row(static_cast<Eigen::Index>(f)) << t[0], t[1], t[2];
    }
    return out;
}

template <class Reader>
MeshData read_with_vtk(const fs::path& path) {
    const vtkSmartPointer<vtkPolyData> poly = detail::read_polydata<Reader>(path);
    MeshData out = from_polydata(poly, path.string());
    if (vtkFieldData* fd = poly->GetFieldData(); fd != nullptr) {
        const auto* text =
            vtkStringArray::SafeDownCast(fd->GetAbstractArray(detail::kProvenanceKey));
        if (text != nullptr && text->GetNumberOfValues() > 0) out.provenance = text->GetValue(0);
    }
    return out;
}

// The text after `prefix` on the first line of `header` that starts with it, else empty.
std::string provenance_in(std::string_view header, std::string_view prefix) {
    std::size_t line = 0;
    while (line < header.size()) {
        const std::size_t end = std::min(header.find('\n', line), header.size());
        std::string_view l = header.substr(line, end - line);
        if (l.ends_with('\r')) l.remove_suffix(1);
        if (l.starts_with(prefix)) return std::string(l.substr(prefix.size()));
        line = end + 1;
    }
    return {};
}

// A PLY file's header (through "end_header"), at most 1 MiB: a hostile file costs no more.
std::string ply_header(const fs::path& path) {
    constexpr std::size_t kMax = std::size_t{1} << 20;
    std::ifstream in(path, std::ios::binary);
    std::string header;
    std::string line;
    while (header.size() < kMax && std::getline(in, line)) {
        header += line;
        header += '\n';
        if (line.starts_with("end_header")) break;
    }
    return header;
}

// ---------------------------------------------------------------- OFF, by hand

class OffParser {
public:
    OffParser(std::string text, std::string name) : text_(std::move(text)), name_(std::move(name)) {}

    std::string_view token() {
        skip_space();
        const std::size_t begin = pos_;
        while (pos_ < text_.size() && !std::isspace(static_cast<unsigned char>(text_[pos_])) &&
               text_[pos_] != '#') {
            ++pos_;
        }
        if (begin == pos_) throw InputError::truncated(name_, "expected a value", pos_);
        return std::string_view(text_).substr(begin, pos_ - begin);
    }
    template <class T>
    T number(const char* what) {
        const std::size_t at = (skip_space(), pos_);
        const std::string_view t = token();
        T value{};
        const auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), value);
        if (ec != std::errc() || ptr != t.data() + t.size()) {
            throw InputError::corrupt(name_, std::string("bad ") + what + " '" +
                                                 std::string(t.substr(0, 32)) + "'", at);
        }
        return value;
    }
    // Skips the rest of the current line (face colours and the like).
    void skip_line() {
        while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
    }
    [[nodiscard]] std::size_t pos() const { return pos_; }
    // The 1-based line holding byte `at`.
    [[nodiscard]] std::size_t line_at(std::size_t at) const {
        const auto end = text_.begin() + static_cast<std::ptrdiff_t>(std::min(at, text_.size()));
        return 1 + static_cast<std::size_t>(std::count(text_.begin(), end, '\n'));
    }
    [[nodiscard]] std::size_t remaining() const { return text_.size() - pos_; }

private:
    void skip_space() {
        while (pos_ < text_.size()) {
            if (text_[pos_] == '#') {
                skip_line();
            } else if (std::isspace(static_cast<unsigned char>(text_[pos_]))) {
                ++pos_;
            } else {
                break;
            }
        }
    }
    std::string text_;
    std::string name_;
    std::size_t pos_ = 0;
};

// ---------------------------------------------------------------- OBJ, by hand
// VTK's OBJ reader stores coordinates as float32 (NaN read as 0, inf and 1e400 as FLT_MAX) and
// crashes on faces naming texture coordinates the file does not have (`f 1/1 2/2 3/3` without
// `vt` lines). This reader keeps what octshape used from it — `v` lines and `f` polygons
// (fan-triangulated), comments and every other statement skipped — and adds: doubles, the
// relative (negative) indices of the OBJ specification, texture and normal indices checked
// for syntax and otherwise ignored (so vertices stay shared, where VTK split a vertex for each
// of its texture coordinates), and every error with its line.

// Parses one signed integer that is the whole of `t`.
bool parse_index(std::string_view t, long long& value) {
    const auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), value);
    return ec == std::errc() && ptr == t.data() + t.size();
}

MeshData parse_obj(std::string_view text, const std::string& name) {
    MeshData out;
    std::vector<std::array<double, 3>> vertices;
    struct Polygon {
        std::size_t line;
        std::size_t at;
        std::vector<long long> ids;  // 0-based, resolved; checked against #V at the end
    };
    std::vector<std::array<int, 3>> triangles;
    std::vector<Polygon> pending;
    const std::string provenance_prefix = std::string("# ") + detail::kProvenanceKey + ' ';
    std::size_t pos = 0;
    std::size_t line_no = 0;
    const auto fail = [&](std::size_t line, std::size_t at, const std::string& what) {
        return InputError::corrupt(name, "line " + std::to_string(line) + ": " + what, at);
    };
    while (pos < text.size()) {
        ++line_no;
        const std::size_t begin = pos;
        const std::size_t eol = std::min(text.find('\n', pos), text.size());
        pos = eol + 1;
        std::string_view line = text.substr(begin, eol - begin);
        if (line.ends_with('\r')) line.remove_suffix(1);
        if (out.provenance.empty() && line.starts_with(provenance_prefix)) {
            out.provenance = std::string(line.substr(provenance_prefix.size()));
            continue;
        }
        // Tokens separated by blanks; a '#' ends the line.
        std::vector<std::string_view> tokens;
        std::size_t i = 0;
        while (i < line.size()) {
            while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
            if (i >= line.size() || line[i] == '#') break;
            const std::size_t b = i;
            while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i])) &&
                   line[i] != '#') {
                ++i;
            }
            tokens.push_back(line.substr(b, i - b));
        }
        if (tokens.empty()) continue;
        const std::size_t at = begin + static_cast<std::size_t>(tokens[0].data() - line.data());
        if (tokens[0] == "v") {
            if (tokens.size() < 4) {
                throw fail(line_no, at, "a vertex needs 3 coordinates, found " +
                                            std::to_string(tokens.size() - 1));
            }
            std::array<double, 3> p{};
            for (int k = 0; k < 3; ++k) {
                const std::string_view t = tokens[static_cast<std::size_t>(k) + 1];
                const auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), p[k]);
                const std::string shown(t.substr(0, 32));
                if (ec == std::errc::result_out_of_range ||
                    (ec == std::errc() && ptr == t.data() + t.size() && !std::isfinite(p[k]))) {
                    throw fail(line_no, at, "coordinate '" + shown + "' is not finite");
                }
                if (ec != std::errc() || ptr != t.data() + t.size()) {
                    throw fail(line_no, at, "bad coordinate '" + shown + "'");
                }
                if (std::abs(p[k]) > kMaxMeshCoordinate) {
                    throw fail(line_no, at, "coordinate " + shown + " beyond ±1e50");
                }
            }
            if (vertices.size() >= static_cast<std::size_t>(std::numeric_limits<int>::max())) {
                throw InputError::unsupported(name, "more than 2^31 vertices", at);
            }
            vertices.push_back(p);
        } else if (tokens[0] == "f") {
            if (tokens.size() < 4) {
                throw fail(line_no, at, "a face needs 3 corners, found " +
                                            std::to_string(tokens.size() - 1));
            }
            Polygon poly{line_no, at, {}};
            poly.ids.reserve(tokens.size() - 1);
            for (std::size_t k = 1; k < tokens.size(); ++k) {
                // v, v/vt, v//vn or v/vt/vn: the vertex index is used, the others only parsed.
                const std::string_view t = tokens[k];
                const std::size_t s1 = t.find('/');
                long long v = 0;
                long long ignored = 0;
                bool ok = parse_index(t.substr(0, s1), v) && v != 0;
                if (ok && s1 != std::string_view::npos) {
                    const std::string_view rest = t.substr(s1 + 1);
                    const std::size_t s2 = rest.find('/');
                    const std::string_view vt = rest.substr(0, s2);
                    ok = (vt.empty() ? s2 != std::string_view::npos : parse_index(vt, ignored));
                    if (ok && s2 != std::string_view::npos) {
                        ok = parse_index(rest.substr(s2 + 1), ignored);
                    }
                }
                if (!ok) {
                    throw fail(line_no, at,
                               "bad face corner '" + std::string(t.substr(0, 32)) + "'");
                }
                // Negative: relative to the vertices read so far (-1 = the last one).
                const long long id = v > 0 ? v - 1 : static_cast<long long>(vertices.size()) + v;
                if (id < 0) {
                    throw fail(line_no, at,
                               "face corner " + std::string(t.substr(0, 32)) +
                                   " refers to a vertex before the first");
                }
                // A fan triangle (0, j, j+1) repeats a vertex iff a corner equals the first
                // or the one before it.
                if (!poly.ids.empty() && (id == poly.ids.front() || id == poly.ids.back())) {
                    throw fail(line_no, at, "face repeats vertex " + std::to_string(id + 1));
                }
                poly.ids.push_back(id);
            }
            pending.push_back(std::move(poly));
        }
        // vt, vn, vp, g, o, s, usemtl, mtllib, l, p and the rest: not part of the surface.
    }
    // Faces may name vertices defined after them: indices are checked once all are read.
    const auto nv = static_cast<long long>(vertices.size());
    for (const Polygon& poly : pending) {
        for (const long long id : poly.ids) {
            if (id >= nv) {
                throw fail(poly.line, poly.at,
                           "face refers to vertex " + std::to_string(id + 1) + " of " +
                               std::to_string(nv));
            }
        }
        for (std::size_t j = 1; j + 1 < poly.ids.size(); ++j) {  // fan triangulation
            triangles.push_back({static_cast<int>(poly.ids[0]), static_cast<int>(poly.ids[j]),
                                 static_cast<int>(poly.ids[j + 1])});
        }
    }
    if (triangles.empty()) throw InputError::corrupt(name, "no triangle in the file");
    out.V.resize(nv, 3);
    for (long long i = 0; i < nv; ++i) {
        const auto& p = vertices[static_cast<std::size_t>(i)];
        out.V.row(i) << p[0], p[1], p[2];
    }
    out.F.resize(static_cast<Eigen::Index>(triangles.size()), 3);
    for (std::size_t f = 0; f < triangles.size(); ++f) {
        out.F.row(static_cast<Eigen::Index>(f)) << triangles[f][0], triangles[f][1],
            triangles[f][2];
    }
    return out;
}

// ---------------------------------------------------------------- writing

template <class Scalars>
void check_scalars(const Scalars& scalars, Eigen::Index expected, const char* kind,
                   const char* elements) {
    for (const auto& [name, values] : scalars) {
        if (values.size() != expected) {
            throw UsageError(std::string(kind) + " scalar '" + name + "' has " +
                             std::to_string(values.size()) + " values for " +
                             std::to_string(expected) + " " + elements);
        }
        if (name.empty() || std::any_of(name.begin(), name.end(), [](unsigned char c) {
                return std::isspace(c) != 0;
            })) {
            throw UsageError(std::string(kind) + " scalar name '" + name + "' must be one word");
        }
    }
}

// Every mesh writer ends here: scalars are checked, then the file is written under a temporary
// name and renamed (io/atomic_file.h).
void write_mesh_file(const fs::path& path,
                     const mesh::Vertices& V,
                     const mesh::Faces& F,
                     const VertexScalars& vertex_scalars,
                     const FaceScalars& face_scalars,
                     const std::string& provenance) {
    const MeshFormat format = mesh_format_from_extension(path);
    check_scalars(vertex_scalars, V.rows(), "vertex", "vertices");
    check_scalars(face_scalars, F.rows(), "face", "faces");
    if (provenance.find_first_of("\r\n") != std::string::npos) {
        throw UsageError("mesh provenance must be one line");
    }
    const std::string dest = path.string();
    switch (format) {
        case MeshFormat::kOff:
            write_file_atomically(dest,
                                  [&](std::ostream& out) { write_off(out, V, F, provenance); });
            return;
        case MeshFormat::kPly:
            write_file_atomically(dest, [&](std::ostream& out) {
                detail::write_ply(out, V, F, vertex_scalars, face_scalars, provenance);
            });
            return;
        case MeshFormat::kObj:
            write_path_atomically(dest, [&](const std::string& tmp) {
                vtkNew<vtkOBJWriter> writer;
                detail::write_polydata(writer.Get(), detail::to_polydata(V, F, {}, {}), tmp,
                                       dest);
                if (provenance.empty()) return;
                // A comment line at the end (VTK's writer has no comment of its own).
                std::ofstream out(tmp, std::ios::app | std::ios::binary);
                out << "# " << detail::kProvenanceKey << ' ' << provenance << '\n';
                if (!out.flush()) throw OutputError(dest, "cannot write the provenance comment");
            });
            return;
        case MeshFormat::kStl:
            write_path_atomically(dest, [&](const std::string& tmp) {
                vtkNew<vtkSTLWriter> writer;
                writer->SetFileTypeToBinary();
                detail::write_polydata(writer.Get(), detail::to_polydata(V, F, {}, {}), tmp,
                                       dest);
            });
            return;
        case MeshFormat::kVtp:
            write_path_atomically(dest, [&](const std::string& tmp) {
                vtkNew<vtkXMLPolyDataWriter> writer;
                const vtkSmartPointer<vtkPolyData> poly =
                    detail::to_polydata(V, F, vertex_scalars, face_scalars);
                if (!provenance.empty()) {
                    vtkNew<vtkStringArray> text;
                    text->SetName(detail::kProvenanceKey);
                    text->InsertNextValue(provenance);
                    poly->GetFieldData()->AddArray(text);
                }
                detail::write_polydata(writer.Get(), poly, tmp, dest);
            });
            return;
    }
}

}  // namespace

MeshFormat mesh_format_from_extension(const fs::path& path) {
    const std::string ext = detail::lower_extension(path);
    if (ext == ".ply") return MeshFormat::kPly;
    if (ext == ".obj") return MeshFormat::kObj;
    if (ext == ".off") return MeshFormat::kOff;
    if (ext == ".stl") return MeshFormat::kStl;
    if (ext == ".vtp") return MeshFormat::kVtp;
    throw UsageError(path.string() +
                     ": unknown mesh file extension (use .ply, .obj, .off, .stl or .vtp)");
}

namespace {
MeshData parse_off(OffParser& p, const std::string& name, const std::string& provenance);
}  // namespace

MeshData read_off(std::istream& in, const std::string& name) {
    std::ostringstream buffer;
    buffer << in.rdbuf();
    std::string text = buffer.str();
    // The provenance comment sits among the leading "OFF" and "#" lines (write_off).
    std::size_t header_end = 0;
    while (header_end < text.size() &&
           (text.compare(header_end, 3, "OFF") == 0 || text[header_end] == '#')) {
        const std::size_t eol = text.find('\n', header_end);
        header_end = eol == std::string::npos ? text.size() : eol + 1;
    }
    const std::string provenance =
        provenance_in(std::string_view(text).substr(0, header_end),
                      std::string("# ") + detail::kProvenanceKey + ' ');
    OffParser p(std::move(text), name);
    try {
        return parse_off(p, name, provenance);
    } catch (const InputError& e) {
        // Name the line as well as the byte: "PATH: corrupt: line 7: bad coordinate ...".
        if (!e.offset()) throw;
        std::string reason = e.reason();
        const std::size_t colon = reason.find(": ");
        const std::string line = "line " + std::to_string(p.line_at(*e.offset())) + ": ";
        reason.insert(colon == std::string::npos ? 0 : colon + 2, line);
        throw InputError(e.kind(), e.path(), reason, e.offset());
    }
}

namespace {

MeshData parse_off(OffParser& p, const std::string& name, const std::string& provenance) {
    const std::string_view magic = p.token();
    if (magic != "OFF") throw InputError::corrupt(name, "does not start with 'OFF'", 0);
    const std::size_t counts_at = p.pos();
    const auto nv = p.number<long long>("vertex count");
    const auto nf = p.number<long long>("face count");
    (void)p.number<long long>("edge count");
    // Each vertex takes at least 6 bytes ("0 0 0\n"), each face at least 8 ("3 0 1 2\n"):
    // reject counts the file cannot hold before allocating for them.
    if (nv < 0 || nf < 0 || nv > static_cast<long long>(p.remaining()) / 6 ||
        nf > static_cast<long long>(p.remaining()) / 8 ||
        nv * 6 + nf * 8 > static_cast<long long>(p.remaining()) + 1) {
        throw InputError::corrupt(name, "vertex/face counts " + std::to_string(nv) + "/" +
                                            std::to_string(nf) + " do not fit the file size",
                                  counts_at);
    }
    if (nv > std::numeric_limits<int>::max()) {
        throw InputError::unsupported(name, "more than 2^31 vertices", counts_at);
    }
    MeshData out;
    out.provenance = provenance;
    out.V.resize(nv, 3);
    for (long long i = 0; i < nv; ++i) {
        for (int k = 0; k < 3; ++k) {
            const std::size_t at = p.pos();
            const auto x = p.number<double>("coordinate");
            if (!std::isfinite(x)) throw InputError::corrupt(name, "coordinate not finite", at);
            if (std::abs(x) > kMaxMeshCoordinate) {
                throw InputError::corrupt(name, "coordinate beyond ±1e50", at);
            }
            out.V(i, k) = x;
        }
        p.skip_line();
    }
    std::vector<std::array<int, 3>> triangles;
    triangles.reserve(static_cast<std::size_t>(nf));
    for (long long f = 0; f < nf; ++f) {
        const std::size_t at = p.pos();
        const auto k = p.number<long long>("polygon size");
        if (k < 3 || k > nv) {
            throw InputError::corrupt(name, "polygon " + std::to_string(f) + " has " +
                                                std::to_string(k) + " corners", at);
        }
        std::vector<int> ids(static_cast<std::size_t>(k));
        for (auto& id : ids) {
            const std::size_t id_at = p.pos();
            const auto v = p.number<long long>("vertex index");
            if (v < 0 || v >= nv) {
                throw InputError::corrupt(name, "polygon " + std::to_string(f) +
                                                    " refers to vertex " + std::to_string(v),
                                          id_at);
            }
            // A fan triangle (0, j, j+1) repeats a vertex iff a corner equals the first or the
            // one before it.
            const std::size_t k_id = static_cast<std::size_t>(&id - ids.data());
            if (k_id > 0 && (v == ids.front() || v == ids[k_id - 1])) {
                throw InputError::corrupt(name, "polygon " + std::to_string(f) +
                                                    " repeats vertex " + std::to_string(v),
                                          id_at);
            }
            id = static_cast<int>(v);
        }
        for (std::size_t j = 1; j + 1 < ids.size(); ++j) triangles.push_back({ids[0], ids[j], ids[j + 1]});
        p.skip_line();
    }
    if (triangles.empty()) throw InputError::corrupt(name, "no triangle in the file");
    out.F.resize(static_cast<Eigen::Index>(triangles.size()), 3);
    for (std::size_t f = 0; f < triangles.size(); ++f) {
        out.F.row(static_cast<Eigen::Index>(f)) << triangles[f][0], triangles[f][1],
            triangles[f][2];
    }
    return out;
}

}  // namespace

MeshData read_obj(std::istream& in, const std::string& name) {
    std::ostringstream buffer;
    buffer << in.rdbuf();
    return parse_obj(buffer.str(), name);
}

MeshData read_mesh(const fs::path& path) {
    check_input_file(path);
    const std::string name = path.string();
    std::error_code ec;
    const auto size = fs::file_size(path, ec);
    if (ec) throw InputError::unreadable(name, ec.message());
    if (size == 0) throw InputError::corrupt(name, "empty file");
    std::array<char, 84> head{};
    {
        std::ifstream in(path, std::ios::binary);
        in.read(head.data(), head.size());
    }
    const std::string_view h(head.data(), static_cast<std::size_t>(std::min<std::uintmax_t>(size, head.size())));
    std::uint32_t stl_count = 0;
    std::memcpy(&stl_count, head.data() + 80, sizeof stl_count);
    if constexpr (std::endian::native == std::endian::big) {
        stl_count = ((stl_count & 0xffu) << 24) | ((stl_count & 0xff00u) << 8) |
                    ((stl_count >> 8) & 0xff00u) | (stl_count >> 24);
    }
    const bool binary_stl = size >= 84 && size == 84 + 50ull * stl_count;

    MeshFormat format;
    if (h.starts_with("ply")) {
        format = MeshFormat::kPly;
    } else if (h.starts_with("OFF")) {
        format = MeshFormat::kOff;
    } else if (h.starts_with("<?xml") || h.starts_with("<VTKFile")) {
        format = MeshFormat::kVtp;
    } else if (binary_stl || h.starts_with("solid")) {
        format = MeshFormat::kStl;
    } else if (detail::lower_extension(path) == ".obj") {
        format = MeshFormat::kObj;
    } else {
        throw InputError::unsupported(name, "not a PLY, OFF, VTP, STL or OBJ mesh", 0);
    }
    switch (format) {
        case MeshFormat::kOff: {
            std::ifstream in(path, std::ios::binary);
            return read_off(in, name);
        }
        case MeshFormat::kPly: {
            MeshData out = read_with_vtk<vtkPLYReader>(path);
            out.provenance = provenance_in(
                ply_header(path), std::string("comment ") + detail::kProvenanceKey + ' ');
            return out;
        }
        case MeshFormat::kObj: {
            std::ifstream in(path, std::ios::binary);
            return read_obj(in, name);
        }
        case MeshFormat::kStl:
            return read_with_vtk<vtkSTLReader>(path);
        case MeshFormat::kVtp:
            return read_with_vtk<vtkXMLPolyDataReader>(path);
    }
    throw InputError::unsupported(name, "unknown mesh format");
}

void write_off(std::ostream& out, const mesh::Vertices& V, const mesh::Faces& F,
               const std::string& provenance) {
    out << "OFF\n";
    if (!provenance.empty()) out << "# " << detail::kProvenanceKey << ' ' << provenance << '\n';
    out << V.rows() << ' ' << F.rows() << " 0\n";
    out << std::setprecision(17);
    for (Eigen::Index i = 0; i < V.rows(); ++i) {
        out << V(i, 0) << ' ' << V(i, 1) << ' ' << V(i, 2) << '\n';
    }
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        out << "3 " << F(f, 0) << ' ' << F(f, 1) << ' ' << F(f, 2) << '\n';
    }
}

void write_mesh(const fs::path& path,
                const mesh::Vertices& V,
                const mesh::Faces& F,
                const FaceScalars& scalars,
                const std::string& provenance) {
    write_mesh_file(path, V, F, {}, scalars, provenance);
}

void write_mesh_vertex_scalars(const fs::path& path,
                               const mesh::Vertices& V,
                               const mesh::Faces& F,
                               const VertexScalars& scalars,
                               const std::string& provenance) {
    const MeshFormat format = mesh_format_from_extension(path);
    if (format != MeshFormat::kVtp && format != MeshFormat::kPly) {
        throw UsageError(path.string() + ": per-vertex scalars need .vtp or .ply");
    }
    write_mesh_file(path, V, F, scalars, {}, provenance);
}

// ---------------------------------------------------------------- shared helpers (detail)

namespace detail {

std::string lower_extension(const fs::path& path) {
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext;
}

namespace {

// Unsigned decimal that is the whole of `t`, or nullopt.
std::optional<unsigned long long> parse_count(std::string_view t) {
    unsigned long long v = 0;
    const auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || ptr != t.data() + t.size() || t.empty()) return std::nullopt;
    return v;
}

std::size_t ply_type_size(std::string_view t) {
    if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
    if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
    if (t == "int" || t == "uint" || t == "float" || t == "int32" || t == "uint32" ||
        t == "float32") {
        return 4;
    }
    if (t == "double" || t == "float64") return 8;
    return 1;  // unknown types: the reader itself refuses them
}

void check_ply_counts(const std::string& name, const std::string& header, std::uintmax_t size) {
    const bool ascii = header.find("\nformat ascii") != std::string::npos;
    struct Element {
        std::string name;
        unsigned long long count = 0;
        std::size_t min_bytes = 0;
    };
    std::vector<Element> elements;
    std::istringstream in(header);
    for (std::string line; std::getline(in, line);) {
        std::istringstream w(line);
        std::string word;
        w >> word;
        if (word == "element") {
            Element e;
            std::string count;
            w >> e.name >> count;
            const auto c = parse_count(count);
            if (!c) throw InputError::corrupt(name, "bad count '" + count + "' of element " + e.name);
            e.count = *c;
            elements.push_back(e);
        } else if (word == "property" && !elements.empty()) {
            std::string type;
            w >> type;
            if (type == "list") w >> type;  // the count's type: a list holds at least that
            elements.back().min_bytes += ascii ? 2 : ply_type_size(type);
        }
    }
    const std::uintmax_t data = size > header.size() ? size - header.size() : 0;
    for (const auto& e : elements) {
        const long double need = static_cast<long double>(e.count) * e.min_bytes;
        if (need > static_cast<long double>(data)) {
            throw InputError::corrupt(name, "element " + e.name + " declares " +
                                                std::to_string(e.count) +
                                                " items, more than the file's " +
                                                std::to_string(data) + " data bytes can hold");
        }
    }
}

void check_vtp_counts(const std::string& name, const std::string& head, std::uintmax_t size) {
    const bool compressed = head.find("compressor=") != std::string::npos;
    for (const char* attribute : {"NumberOfPoints=\"", "NumberOfPolys=\"", "NumberOfVerts=\"",
                                  "NumberOfLines=\"", "NumberOfStrips=\""}) {
        const std::string a(attribute);
        for (std::size_t at = head.find(a); at != std::string::npos; at = head.find(a, at + 1)) {
            const std::size_t begin = at + a.size();
            const std::size_t end = head.find('"', begin);
            if (end == std::string::npos) break;
            const auto c = parse_count(std::string_view(head).substr(begin, end - begin));
            if (!c) continue;  // the reader reports a malformed attribute itself
            const long double need = static_cast<long double>(*c) / (compressed ? 10000.0L : 1.0L);
            if (need > static_cast<long double>(size)) {
                throw InputError::corrupt(name, a.substr(0, a.size() - 2) + " " +
                                                    std::to_string(*c) + " does not fit the file's " +
                                                    std::to_string(size) + " bytes",
                                          at);
            }
        }
    }
}

}  // namespace

void check_declared_counts(const fs::path& path) {
    std::error_code ec;
    const auto size = fs::file_size(path, ec);
    if (ec) return;  // the reader reports it
    constexpr std::size_t kHead = std::size_t{1} << 20;
    std::string head(kHead, '\0');
    {
        std::ifstream in(path, std::ios::binary);
        in.read(head.data(), static_cast<std::streamsize>(head.size()));
        head.resize(static_cast<std::size_t>(in.gcount()));
    }
    if (head.starts_with("ply")) {
        check_ply_counts(path.string(), ply_header(path), size);
    } else if (head.starts_with("<?xml") || head.starts_with("<VTKFile")) {
        // Only the XML before the appended data: its binary bytes could mimic an attribute.
        const std::size_t appended = head.find("<AppendedData");
        check_vtp_counts(path.string(), head.substr(0, appended), size);
    }
}

vtkSmartPointer<vtkPolyData> to_polydata(const mesh::Vertices& V,
                                         const mesh::Faces& F,
                                         const VertexScalars& vertex_scalars,
                                         const FaceScalars& face_scalars) {
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
    auto poly = vtkSmartPointer<vtkPolyData>::New();
    poly->SetPoints(points);
    poly->SetPolys(polys);
    const auto add = [](const auto& scalars, vtkDataSetAttributes* data) {
        for (const auto& [name, values] : scalars) {
            vtkNew<vtkDoubleArray> array;
            array->SetName(name.c_str());
            array->SetNumberOfValues(values.size());
            for (Eigen::Index i = 0; i < values.size(); ++i) array->SetValue(i, values(i));
            data->AddArray(array);
        }
    };
    add(vertex_scalars, poly->GetPointData());
    add(face_scalars, poly->GetCellData());
    return poly;
}

void write_ply(std::ostream& out,
               const mesh::Vertices& V,
               const mesh::Faces& F,
               const VertexScalars& vertex_scalars,
               const FaceScalars& face_scalars,
               const std::string& provenance) {
    out << "ply\nformat binary_little_endian 1.0\ncomment written by octshape\n";
    if (!provenance.empty()) out << "comment " << kProvenanceKey << ' ' << provenance << '\n';
    out
        << "element vertex " << V.rows() << "\nproperty double x\nproperty double y\n"
        << "property double z\n";
    for (const auto& s : vertex_scalars) out << "property double " << s.first << '\n';
    const bool faces = F.rows() > 0 || !face_scalars.empty();
    if (faces) {
        out << "element face " << F.rows() << "\nproperty list uchar int vertex_indices\n";
        for (const auto& s : face_scalars) out << "property double " << s.first << '\n';
    }
    out << "end_header\n";
    for (Eigen::Index i = 0; i < V.rows(); ++i) {
        for (int k = 0; k < 3; ++k) put_le<double>(out, V(i, k));
        for (const auto& s : vertex_scalars) put_le<double>(out, s.second(i));
    }
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        put_le<std::uint8_t>(out, 3);
        for (int k = 0; k < 3; ++k) put_le<std::int32_t>(out, F(f, k));
        for (const auto& s : face_scalars) put_le<double>(out, s.second(f));
    }
}

}  // namespace detail

}  // namespace octshape::io
