#include "denoise_setup.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <string>

#include "simd.h"

namespace octshape::mesh::detail {

namespace {

// The 10 low bits of x spread to every third bit (bit b to bit 3b).
std::uint64_t spread3(std::uint32_t x) {
    std::uint64_t v = x & 0x3ffu;
    v = (v | v << 16) & 0x30000ffull;
    v = (v | v << 8) & 0x300f00full;
    v = (v | v << 4) & 0x30c30c3ull;
    v = (v | v << 2) & 0x9249249ull;
    return v;
}

// Sorts keys (Morton code in bits 32–61, face in bits 0–31, built in ascending face order)
// by their code: a least-significant-digit radix sort, three passes of 10 bits. Each pass is
// stable, so faces with equal codes stay in ascending order: the order std::sort gives the
// whole keys, in ≈ 30 instructions a key instead of ≈ 200.
void sort_by_code(std::vector<std::uint64_t>& key) {
    std::vector<std::uint64_t> out(key.size());
    for (int pass = 0; pass < 3; ++pass) {
        const int shift = 32 + 10 * pass;
        std::vector<std::size_t> start(1025, 0);
        for (const std::uint64_t k : key) ++start[((k >> shift) & 0x3ffu) + 1];
        for (std::size_t b = 0; b < 1024; ++b) start[b + 1] += start[b];
        for (const std::uint64_t k : key) out[start[(k >> shift) & 0x3ffu]++] = k;
        key.swap(out);
    }
}

}  // namespace

LocalOrder local_order(const Vertices& V, const Faces& F) {
    const auto m = static_cast<std::size_t>(F.rows());
    const double* v = V.data();
    const int* tri = F.data();
    std::vector<double> centroid(3 * m);
    double lo[3] = {0.0, 0.0, 0.0};
    double hi[3] = {0.0, 0.0, 0.0};
    for (std::size_t f = 0; f < m; ++f) {
        for (int k = 0; k < 3; ++k) {
            const double c = (v[3 * static_cast<std::ptrdiff_t>(tri[3 * f]) + k] +
                              v[3 * static_cast<std::ptrdiff_t>(tri[3 * f + 1]) + k] +
                              v[3 * static_cast<std::ptrdiff_t>(tri[3 * f + 2]) + k]) / 3.0;
            centroid[3 * f + k] = c;
            lo[k] = f == 0 ? c : std::min(lo[k], c);
            hi[k] = f == 0 ? c : std::max(hi[k], c);
        }
    }
    // One scale for all three axes (a cube: the curve's cells are cubes on the surface).
    const double extent = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
    const double scale = extent > 0.0 ? 1023.0 / extent : 0.0;
    // key = Morton code << 32 | face: sorting the keys sorts by the code, ties by the face.
    std::vector<std::uint64_t> key(m);
    for (std::size_t f = 0; f < m; ++f) {
        std::uint64_t code = 0;
        for (int k = 0; k < 3; ++k) {
            const double q = std::clamp((centroid[3 * f + k] - lo[k]) * scale, 0.0, 1023.0);
            code |= spread3(static_cast<std::uint32_t>(q)) << k;
        }
        key[f] = code << 32 | f;
    }
    sort_by_code(key);
    LocalOrder out;
    out.F.resize(F.rows(), 3);
    std::vector<int> local(static_cast<std::size_t>(V.rows()), -1);
    out.vertex.reserve(static_cast<std::size_t>(V.rows()));
    int* const renamed = out.F.data();
    for (std::size_t k = 0; k < m; ++k) {
        const std::size_t f = key[k] & 0xffffffffu;
        for (int c = 0; c < 3; ++c) {
            const int i = tri[3 * f + c];
            int& l = local[static_cast<std::size_t>(i)];
            if (l < 0) {
                l = static_cast<int>(out.vertex.size());
                out.vertex.push_back(i);
            }
            renamed[3 * k + c] = l;
        }
    }
    out.V.resize(static_cast<Eigen::Index>(out.vertex.size()), 3);
    for (std::size_t k = 0; k < out.vertex.size(); ++k) {
        out.V.row(static_cast<Eigen::Index>(k)) = V.row(out.vertex[k]);
    }
    return out;
}

void to_caller_order(const Vertices& X, const LocalOrder& order, Vertices& out) {
    for (std::size_t k = 0; k < order.vertex.size(); ++k) {
        out.row(order.vertex[k]) = X.row(static_cast<Eigen::Index>(k));
    }
}

DenoiseSetup prepare_denoise(const Vertices& V,
                             const Faces& F,
                             std::optional<double> radius,
                             double radius_factor,
                             bool fix_boundary,
                             int iterations,
                             int threads,
                             DenoiseResult& result) {
    const auto t0 = std::chrono::steady_clock::now();
    DenoiseSetup s;
    result.V = V;
    const auto n = static_cast<int>(V.rows());
    s.adjacency = build_adjacency(F, n);
    if (s.adjacency.nonmanifold_edges > 0) {
        result.warnings.push_back(std::to_string(s.adjacency.nonmanifold_edges) +
                                  " non-manifold edges: their vertices are kept fixed");
    }
    s.geometry = face_geometry(V, F);
    const double ca = mean_centroid_distance(s.geometry, s.adjacency);
    result.mean_centroid_distance = ca;
    result.radius = radius.value_or(radius_factor * ca);
    s.fixed.assign(static_cast<std::size_t>(n), 0);
    if (fix_boundary) s.fixed = s.adjacency.boundary_vertex;
    for (const auto f : s.fixed) result.fixed_vertices += f;
    s.run = iterations > 0 && F.rows() > 0 && result.radius > 0.0;
    if (s.run) {
        s.omega = disk_neighbourhoods(F, s.geometry, s.adjacency, result.radius, threads);
        result.mean_neighbourhood =
            static_cast<double>(s.omega.items.size()) / static_cast<double>(F.rows());
    }
    result.seconds_setup =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return s;
}

namespace {

// Lanes 0–2 = x, y, z; lane 3 is carried along and never read.
[[gnu::always_inline]] inline V4d load3(const double* p) { return V4d{p[0], p[1], p[2], 0.0}; }

// Half h of a face record: 0 = normal and area, 1 = centroid and padding.
[[gnu::always_inline]] inline V4d face_half(const FaceState& f, int h) {
    static_assert(sizeof(FaceState) == 2 * sizeof(V4d));
    V4d v;
    std::memcpy(&v, reinterpret_cast<const unsigned char*>(&f) + h * sizeof v, sizeof v);
    return v;
}

// a·b over lanes 0–2, added in the order (a0 b0 + a1 b1) + a2 b2.
[[gnu::always_inline]] inline double dot3(const V4d& a, const V4d& b) {
    const V4d p = a * b;
    return p[0] + p[1] + p[2];
}

// Recomputes normal, area and centroid of faces [begin, end). The x, y, z components are the
// lanes 0–2 of a V4d; each lane does the scalar formula's IEEE operations for its component
// (the cross product's lane x: e1_y e2_z − e1_z e2_y, and so on), in the same order.
[[gnu::always_inline]] inline void update_faces_impl(const Vertices& V, const Faces& F,
                                                     int begin, int end, FaceState* faces) {
    const double* v = V.data();  // row-major: vertex i at v[3i .. 3i+2]
    const int* tri = F.data();
    for (int f = begin; f < end; ++f) {
        const V4d a = load3(v + 3 * static_cast<std::ptrdiff_t>(tri[3 * f]));
        const V4d b = load3(v + 3 * static_cast<std::ptrdiff_t>(tri[3 * f + 1]));
        const V4d c = load3(v + 3 * static_cast<std::ptrdiff_t>(tri[3 * f + 2]));
        const V4d e1 = b - a;
        const V4d e2 = c - a;
        const V4d cross = __builtin_shufflevector(e1, e1, 1, 2, 0, 3) *
                              __builtin_shufflevector(e2, e2, 2, 0, 1, 3) -
                          __builtin_shufflevector(e1, e1, 2, 0, 1, 3) *
                              __builtin_shufflevector(e2, e2, 1, 2, 0, 3);
        const double norm = std::sqrt(dot3(cross, cross));
        const double inv = norm > 0.0 ? 1.0 / norm : 0.0;  // zero normal for a degenerate face
        const V4d normal = cross * splat(inv);
        const V4d centroid = (a + b + c) / splat(3.0);  // Eq. 2.31; lane 3 = 0 (padding)
        // (normal, area), (centroid, 0): the two halves of the record.
        const V4d h0 = __builtin_shufflevector(normal, splat(0.5 * norm), 0, 1, 2, 4);
        unsigned char* rec = reinterpret_cast<unsigned char*>(faces + f);
        std::memcpy(rec, &h0, sizeof h0);
        std::memcpy(rec + sizeof h0, &centroid, sizeof centroid);
    }
}

// The x, y, z components are the lanes 0–2 of a V4d (simd.h): each lane does the IEEE double
// operations the scalar formula (vertex_step_scalar) does for its component, in the same
// order. Inlined into the AVX2 copy.
[[gnu::always_inline]] inline void vertex_step_impl(const Vertices& V,
                                                    const FaceState* faces,
                                                    const Adjacency& adjacency,
                                                    const std::vector<std::uint8_t>& fixed,
                                                    double lambda_i,
                                                    int begin,
                                                    int end,
                                                    Vertices& out) {
    const int* vf_off = adjacency.vertex_faces.offsets.data();
    const int* vf = adjacency.vertex_faces.items.data();
    const int* vv_off = adjacency.vertex_vertices.offsets.data();
    const int* vv = adjacency.vertex_vertices.items.data();
    const double* v = V.data();
    double* o = out.data();
    for (int i = begin; i < end; ++i) {
        const V4d vi = load3(v + 3 * static_cast<std::ptrdiff_t>(i));
        const int fb = vf_off[i];
        const int fe = vf_off[i + 1];
        if (fixed[static_cast<std::size_t>(i)] != 0 || fb == fe) {
            for (int k = 0; k < 3; ++k) o[3 * i + k] = vi[k];
            continue;
        }
        V4d step = splat(0.0);
        V4d normal = splat(0.0);
        if (lambda_i != 0.0) {
            for (int p = fb; p < fe; ++p) {
                const FaceState& s = faces[vf[p]];
                const V4d nk = face_half(s, 0);  // ñ_k, a_k
                const double d = dot3(nk, face_half(s, 1) - vi);
                step = step + splat(d) * nk;             // Eq. 5.9 / 3.7, edge term
                normal = normal + splat(s.area) * nk;    // Eq. 5.7
            }
        } else {
            // The same edge term; Eq. 5.7's normal is read only by the λ_I term.
            for (int p = fb; p < fe; ++p) {
                const FaceState& s = faces[vf[p]];
                const V4d nk = face_half(s, 0);
                step = step + splat(dot3(nk, face_half(s, 1) - vi)) * nk;
            }
        }
        step = step * splat(1.0 / static_cast<double>(fe - fb));
        if (lambda_i != 0.0) {
            // Eq. 5.6: D_i = Σ w_ij v_j / Σ w_ij − v_i with w_ij = |v_i − v_j|².
            V4d weighted = splat(0.0);
            double weight = 0.0;
            for (int p = vv_off[i]; p < vv_off[i + 1]; ++p) {
                const V4d vj = load3(v + 3 * static_cast<std::ptrdiff_t>(vv[p]));
                const V4d dv = vi - vj;
                const double w = dot3(dv, dv);
                weighted = weighted + splat(w) * vj;
                weight += w;
            }
            if (weight > 0.0) {
                const V4d d = weighted / splat(weight) - vi;
                // Eq. 5.7 normalised to unit length so that Eq. 5.8 is a true projection.
                const double len = std::sqrt(dot3(normal, normal));
                const double inv_len = len > 0.0 ? 1.0 / len : 0.0;
                const V4d nv = normal * splat(inv_len);
                const double dn = dot3(d, nv);
                step = step + splat(lambda_i) * (d + (d - splat(dn) * nv));  // Eq. 5.5, 5.8, 5.9
            }
        }
        const V4d r = vi + step;
        for (int k = 0; k < 3; ++k) o[3 * i + k] = r[k];
    }
}

__attribute__((target("avx2"))) void vertex_step_avx2(const Vertices& V,
                                                      const FaceState* faces,
                                                      const Adjacency& adjacency,
                                                      const std::vector<std::uint8_t>& fixed,
                                                      double lambda_i, int begin, int end,
                                                      Vertices& out) {
    vertex_step_impl(V, faces, adjacency, fixed, lambda_i, begin, end, out);
}

// The baseline copies: the same formulas on scalars (GCC lowers 4-double vectors to SSE2
// poorly); each component gets the same IEEE operations in the same order as a lane of the
// AVX2 copies, so the results are the same bits (test Rofi.BaselineAndAvx2KernelsGiveTheSameBits).
void update_faces_scalar(const Vertices& V, const Faces& F, int begin, int end,
                         FaceState* faces) {
    const double* v = V.data();  // row-major: vertex i at v[3i .. 3i+2]
    const int* tri = F.data();
    for (int f = begin; f < end; ++f) {
        const double* a = v + 3 * static_cast<std::ptrdiff_t>(tri[3 * f]);
        const double* b = v + 3 * static_cast<std::ptrdiff_t>(tri[3 * f + 1]);
        const double* c = v + 3 * static_cast<std::ptrdiff_t>(tri[3 * f + 2]);
        const double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        const double e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        const double x = e1[1] * e2[2] - e1[2] * e2[1];
        const double y = e1[2] * e2[0] - e1[0] * e2[2];
        const double z = e1[0] * e2[1] - e1[1] * e2[0];
        const double norm = std::sqrt(x * x + y * y + z * z);
        FaceState& s = faces[f];
        s.area = 0.5 * norm;
        const double inv = norm > 0.0 ? 1.0 / norm : 0.0;  // zero normal for a degenerate face
        s.normal[0] = x * inv;
        s.normal[1] = y * inv;
        s.normal[2] = z * inv;
        for (int k = 0; k < 3; ++k) s.centroid[k] = (a[k] + b[k] + c[k]) / 3.0;  // Eq. 2.31
        s.unused = 0.0;
    }
}

void vertex_step_scalar(const Vertices& V,
                        const FaceState* faces,
                        const Adjacency& adjacency,
                        const std::vector<std::uint8_t>& fixed,
                        double lambda_i,
                        int begin,
                        int end,
                        Vertices& out) {
    const int* vf_off = adjacency.vertex_faces.offsets.data();
    const int* vf = adjacency.vertex_faces.items.data();
    const int* vv_off = adjacency.vertex_vertices.offsets.data();
    const int* vv = adjacency.vertex_vertices.items.data();
    const double* v = V.data();
    double* o = out.data();
    for (int i = begin; i < end; ++i) {
        const double vi[3] = {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
        const int fb = vf_off[i];
        const int fe = vf_off[i + 1];
        if (fixed[static_cast<std::size_t>(i)] != 0 || fb == fe) {
            for (int k = 0; k < 3; ++k) o[3 * i + k] = vi[k];
            continue;
        }
        double step[3] = {0.0, 0.0, 0.0};
        double normal[3] = {0.0, 0.0, 0.0};
        for (int p = fb; p < fe; ++p) {
            const FaceState& s = faces[vf[p]];
            const double* nk = s.normal;
            const double d = nk[0] * (s.centroid[0] - vi[0]) + nk[1] * (s.centroid[1] - vi[1]) +
                             nk[2] * (s.centroid[2] - vi[2]);
            for (int k = 0; k < 3; ++k) {
                step[k] += d * nk[k];             // Eq. 5.9 / 3.7, edge term
                if (lambda_i != 0.0) normal[k] += s.area * nk[k];  // Eq. 5.7, read by λ_I only
            }
        }
        const double inv_faces = 1.0 / static_cast<double>(fe - fb);
        for (double& s : step) s *= inv_faces;
        if (lambda_i != 0.0) {
            // Eq. 5.6: D_i = Σ w_ij v_j / Σ w_ij − v_i with w_ij = |v_i − v_j|².
            double weighted[3] = {0.0, 0.0, 0.0};
            double weight = 0.0;
            for (int p = vv_off[i]; p < vv_off[i + 1]; ++p) {
                const double* vj = v + 3 * static_cast<std::ptrdiff_t>(vv[p]);
                const double dx = vi[0] - vj[0];
                const double dy = vi[1] - vj[1];
                const double dz = vi[2] - vj[2];
                const double w = dx * dx + dy * dy + dz * dz;
                for (int k = 0; k < 3; ++k) weighted[k] += w * vj[k];
                weight += w;
            }
            if (weight > 0.0) {
                double d[3];
                for (int k = 0; k < 3; ++k) d[k] = weighted[k] / weight - vi[k];
                // Eq. 5.7 normalised to unit length so that Eq. 5.8 is a true projection.
                const double len = std::sqrt(normal[0] * normal[0] + normal[1] * normal[1] +
                                             normal[2] * normal[2]);
                const double inv_len = len > 0.0 ? 1.0 / len : 0.0;
                double nv[3];
                for (int k = 0; k < 3; ++k) nv[k] = normal[k] * inv_len;
                const double dn = d[0] * nv[0] + d[1] * nv[1] + d[2] * nv[2];
                for (int k = 0; k < 3; ++k) {
                    step[k] += lambda_i * (d[k] + (d[k] - dn * nv[k]));  // Eq. 5.5, 5.8, 5.9
                }
            }
        }
        for (int k = 0; k < 3; ++k) o[3 * i + k] = vi[k] + step[k];
    }
}

__attribute__((target("avx2"))) void update_faces_avx2(const Vertices& V, const Faces& F,
                                                       int begin, int end, FaceState* faces) {
    update_faces_impl(V, F, begin, end, faces);
}

}  // namespace

void vertex_step(const Vertices& V,
                 const FaceState* faces,
                 const Adjacency& adjacency,
                 const std::vector<std::uint8_t>& fixed,
                 double lambda_i,
                 int begin,
                 int end,
                 Vertices& out,
                 bool avx2) {
    if (avx2) {
        vertex_step_avx2(V, faces, adjacency, fixed, lambda_i, begin, end, out);
    } else {
        vertex_step_scalar(V, faces, adjacency, fixed, lambda_i, begin, end, out);
    }
}

void update_faces(const Vertices& V, const Faces& F, int begin, int end, FaceState* faces,
                  bool avx2) {
    if (avx2) {
        update_faces_avx2(V, F, begin, end, faces);
    } else {
        update_faces_scalar(V, F, begin, end, faces);
    }
}

}  // namespace octshape::mesh::detail
