#pragma once
// Meshes with known geometry for the libmesh tests: closed (icosphere, cube), open (plane
// grid), and the same with reproducible Gaussian noise.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "octshape/mesh/mesh.h"

namespace octshape::test {

struct TestMesh {
    std::string name;
    mesh::Vertices V;
    mesh::Faces F;
};

// (n+1)×(n+1) vertices on [0, size]² at z = 0, each square split along its diagonal into two
// counter-clockwise triangles (normals +z).
inline TestMesh plane_grid(int n, double size = 1.0) {
    TestMesh m{"plane", mesh::Vertices((n + 1) * (n + 1), 3), mesh::Faces(2 * n * n, 3)};
    const double h = size / n;
    for (int j = 0; j <= n; ++j) {
        for (int i = 0; i <= n; ++i) m.V.row(j * (n + 1) + i) << i * h, j * h, 0.0;
    }
    int f = 0;
    for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
            const int a = j * (n + 1) + i;
            const int b = a + 1;
            const int c = a + n + 2;
            const int d = a + n + 1;
            m.F.row(f++) << a, b, c;
            m.F.row(f++) << a, c, d;
        }
    }
    return m;
}

// Unit icosphere: the icosahedron with each triangle split into 4, `levels` times, projected
// onto the sphere of radius `radius`; outward orientation.
inline TestMesh icosphere(int levels, double radius = 1.0) {
    const double t = (1.0 + std::sqrt(5.0)) / 2.0;
    std::vector<Eigen::Vector3d> v = {{-1, t, 0}, {1, t, 0},  {-1, -t, 0}, {1, -t, 0},
                                      {0, -1, t}, {0, 1, t},  {0, -1, -t}, {0, 1, -t},
                                      {t, 0, -1}, {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
    std::vector<std::array<int, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10},
                                         {0, 10, 11}, {1, 5, 9}, {5, 11, 4},  {11, 10, 2},
                                         {10, 7, 6}, {7, 1, 8},  {3, 9, 4},   {3, 4, 2},
                                         {3, 2, 6},  {3, 6, 8},  {3, 8, 9},   {4, 9, 5},
                                         {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    for (auto& p : v) p.normalize();
    for (int l = 0; l < levels; ++l) {
        std::map<std::pair<int, int>, int> mid;
        const auto midpoint = [&](int a, int b) {
            const auto key = std::minmax(a, b);
            const auto it = mid.find(key);
            if (it != mid.end()) return it->second;
            v.push_back((v[static_cast<std::size_t>(a)] + v[static_cast<std::size_t>(b)]).normalized());
            const int id = static_cast<int>(v.size()) - 1;
            mid.emplace(key, id);
            return id;
        };
        std::vector<std::array<int, 3>> next;
        for (const auto& tri : f) {
            const int ab = midpoint(tri[0], tri[1]);
            const int bc = midpoint(tri[1], tri[2]);
            const int ca = midpoint(tri[2], tri[0]);
            next.push_back({tri[0], ab, ca});
            next.push_back({tri[1], bc, ab});
            next.push_back({tri[2], ca, bc});
            next.push_back({ab, bc, ca});
        }
        f = std::move(next);
    }
    TestMesh m{"sphere", mesh::Vertices(static_cast<Eigen::Index>(v.size()), 3),
               mesh::Faces(static_cast<Eigen::Index>(f.size()), 3)};
    for (std::size_t i = 0; i < v.size(); ++i) m.V.row(static_cast<Eigen::Index>(i)) = radius * v[i];
    for (std::size_t i = 0; i < f.size(); ++i) {
        m.F.row(static_cast<Eigen::Index>(i)) << f[i][0], f[i][1], f[i][2];
    }
    return m;
}

// Cube [−1, 1]³, each side an n×n grid of squares split into two triangles, outward normals,
// shared vertices along the edges (a closed manifold).
inline TestMesh cube(int n) {
    std::map<std::array<long, 3>, int> index;
    std::vector<Eigen::Vector3d> v;
    std::vector<std::array<int, 3>> f;
    const auto vertex = [&](const Eigen::Vector3d& p) {
        const std::array<long, 3> key{std::lround(p.x() * n * 2), std::lround(p.y() * n * 2),
                                      std::lround(p.z() * n * 2)};
        const auto it = index.find(key);
        if (it != index.end()) return it->second;
        v.push_back(p);
        index.emplace(key, static_cast<int>(v.size()) - 1);
        return static_cast<int>(v.size()) - 1;
    };
    for (int axis = 0; axis < 3; ++axis) {
        for (const double side : {-1.0, 1.0}) {
            Eigen::Vector3d normal = Eigen::Vector3d::Zero();
            normal(axis) = side;
            Eigen::Vector3d u = Eigen::Vector3d::Zero();
            u((axis + 1) % 3) = 1.0;
            const Eigen::Vector3d w = normal.cross(u);  // u × w = normal: counter-clockwise
            for (int j = 0; j < n; ++j) {
                for (int i = 0; i < n; ++i) {
                    const auto at = [&](int a, int b) {
                        return vertex(normal + (-1.0 + 2.0 * a / n) * u + (-1.0 + 2.0 * b / n) * w);
                    };
                    const int p00 = at(i, j);
                    const int p10 = at(i + 1, j);
                    const int p11 = at(i + 1, j + 1);
                    const int p01 = at(i, j + 1);
                    f.push_back({p00, p10, p11});
                    f.push_back({p00, p11, p01});
                }
            }
        }
    }
    TestMesh m{"cube", mesh::Vertices(static_cast<Eigen::Index>(v.size()), 3),
               mesh::Faces(static_cast<Eigen::Index>(f.size()), 3)};
    for (std::size_t i = 0; i < v.size(); ++i) m.V.row(static_cast<Eigen::Index>(i)) = v[i];
    for (std::size_t i = 0; i < f.size(); ++i) {
        m.F.row(static_cast<Eigen::Index>(i)) << f[i][0], f[i][1], f[i][2];
    }
    return m;
}

// Standard normal deviates from a fixed-seed mt19937 through Box–Muller (std::normal_distribution
// is implementation-defined; this is the same on every platform).
class Gaussian {
public:
    explicit Gaussian(std::uint32_t seed) : rng_(seed) {}
    double operator()() {
        const double u1 = (static_cast<double>(rng_()) + 1.0) / 4294967297.0;
        const double u2 = static_cast<double>(rng_()) / 4294967296.0;
        return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * 3.14159265358979323846 * u2);
    }

private:
    std::mt19937 rng_;
};

// Adds Gaussian noise of standard deviation sigma in each coordinate (random direction).
inline TestMesh with_noise(TestMesh m, double sigma, std::uint32_t seed = 7) {
    Gaussian g(seed);
    for (Eigen::Index i = 0; i < m.V.rows(); ++i) {
        for (int k = 0; k < 3; ++k) m.V(i, k) += sigma * g();
    }
    m.name += "+noise";
    return m;
}

// Vertex normals: the normalised sum of the area-weighted normals of each vertex's faces.
inline mesh::Vertices vertex_normals(const mesh::Vertices& V, const mesh::Faces& F) {
    mesh::Vertices n = mesh::Vertices::Zero(V.rows(), 3);
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        const Eigen::Vector3d a = V.row(F(f, 0));
        const Eigen::Vector3d b = V.row(F(f, 1));
        const Eigen::Vector3d c = V.row(F(f, 2));
        const Eigen::Vector3d w = (b - a).cross(c - a);  // 2 × area × unit normal
        for (int k = 0; k < 3; ++k) n.row(F(f, k)) += w.transpose();
    }
    n.rowwise().normalize();
    return n;
}

// Adds Gaussian noise of standard deviation sigma along each vertex normal of the clean mesh.
inline TestMesh with_normal_noise(TestMesh m, double sigma, std::uint32_t seed = 7) {
    const mesh::Vertices n = vertex_normals(m.V, m.F);
    Gaussian g(seed);
    for (Eigen::Index i = 0; i < m.V.rows(); ++i) m.V.row(i) += sigma * g() * n.row(i);
    m.name += "+normal-noise";
    return m;
}

// Organic detail: the icosphere of `levels` with each vertex at radius
// 1 + amplitude · Σ_j sin(ω_j · d + φ_j) / √J along its direction d, J = 12 plane waves, half
// of wavenumber 6 and half of 16 (wavelengths ≈ 1.05 and 0.39 on the unit sphere; level 5
// has edges ≈ 0.06, so the fine relief spans ~6 edges), random directions and phases from
// `seed`. Known clean geometry: the mesh itself.
inline TestMesh relief_sphere(int levels, double amplitude = 0.04, std::uint32_t seed = 11) {
    TestMesh m = icosphere(levels);
    Gaussian g(seed);
    constexpr int kWaves = 12;
    std::vector<Eigen::Vector3d> omega;
    std::vector<double> phase;
    for (int j = 0; j < kWaves; ++j) {
        Eigen::Vector3d w(g(), g(), g());
        omega.push_back(w.normalized() * (j < kWaves / 2 ? 6.0 : 16.0));
        phase.push_back(g());
    }
    for (Eigen::Index i = 0; i < m.V.rows(); ++i) {
        const Eigen::Vector3d d = m.V.row(i).normalized();
        double h = 0.0;
        for (int j = 0; j < kWaves; ++j) h += std::sin(omega[j].dot(d) + phase[j]);
        m.V.row(i) = (1.0 + amplitude * h / std::sqrt(double{kWaves})) * d.transpose();
    }
    m.name = "relief_sphere";
    return m;
}

// Super-ellipsoid |x|^e + |y|^e + |z|^e = 1: the icosphere of `levels` projected radially onto
// it (e = 2 the sphere; e = 6 a cube with rounded edges of radius ~0.3).
inline TestMesh superellipsoid(int levels, double e = 6.0) {
    TestMesh m = icosphere(levels);
    for (Eigen::Index i = 0; i < m.V.rows(); ++i) {
        const Eigen::Vector3d d = m.V.row(i).normalized();
        const double s = std::pow(std::pow(std::abs(d.x()), e) + std::pow(std::abs(d.y()), e) +
                                      std::pow(std::abs(d.z()), e),
                                  -1.0 / e);
        m.V.row(i) = s * d.transpose();
    }
    m.name = "superellipsoid";
    return m;
}

// The family the property tests loop over: closed smooth, closed sharp, open; noisy.
inline std::vector<TestMesh> noisy_family() {
    return {with_noise(icosphere(3), 0.02), with_noise(cube(6), 0.03),
            with_noise(plane_grid(16), 0.015)};
}

// The mesh with its vertices renamed by `vertex_perm` (new index of old vertex i) and its
// faces put in the order `face_perm` (new face k = old face face_perm[k]), corners kept.
inline TestMesh permuted(const TestMesh& m, const std::vector<int>& vertex_perm,
                         const std::vector<int>& face_perm) {
    const auto at = [](const std::vector<int>& p, Eigen::Index i) {
        return p[static_cast<std::size_t>(i)];
    };
    TestMesh out{m.name, mesh::Vertices(m.V.rows(), 3), mesh::Faces(m.F.rows(), 3)};
    for (Eigen::Index i = 0; i < m.V.rows(); ++i) out.V.row(at(vertex_perm, i)) = m.V.row(i);
    for (Eigen::Index k = 0; k < m.F.rows(); ++k) {
        for (int c = 0; c < 3; ++c) out.F(k, c) = at(vertex_perm, m.F(at(face_perm, k), c));
    }
    return out;
}

// 0, 1, …, n − 1; shuffled: the same in a reproducible random order.
inline std::vector<int> identity(Eigen::Index n) {
    std::vector<int> p(static_cast<std::size_t>(n));
    for (std::size_t i = 0; i < p.size(); ++i) p[i] = static_cast<int>(i);
    return p;
}

inline std::vector<int> shuffled(Eigen::Index n, std::uint32_t seed) {
    std::vector<int> p = identity(n);
    std::mt19937 rng(seed);
    std::shuffle(p.begin(), p.end(), rng);
    return p;
}

}  // namespace octshape::test
