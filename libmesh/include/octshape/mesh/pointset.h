#pragma once
// Point sets: a k-d tree, PCA normals with a consistent orientation, and the point-set NVT
// denoiser of thesis §4 (vertex-based normal voting tensor, feature classification by the
// anisotropic covariance, restricted quadric vertex updates under a deviation bound).
// docs/algorithms/pointset.md explains the equations, defaults and decisions.
//
// A point set is a Vertices array (#P×3, mesh.h) without faces. Normals are #P×3 unit rows.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "octshape/mesh/mesh.h"

namespace octshape::mesh {

// A static k-d tree over the rows of a #P×3 array (its own copy), built once in
// O(#P log #P). Leaves hold at most 8 points. Queries are thread-safe.
class KdTree {
public:
    // Throws DataError if a coordinate is not finite.
    explicit KdTree(const Vertices& points);

    // The k nearest points to p (fewer if the tree holds fewer), nearest first; ties broken by
    // the smaller index so that results are reproducible.
    [[nodiscard]] std::vector<int> nearest(const Eigen::Vector3d& p, int k) const;

    // Every point within distance `radius` of p (inclusive), in ascending index order.
    [[nodiscard]] std::vector<int> within(const Eigen::Vector3d& p, double radius) const;
    // The same points into `out` (cleared first; its capacity is reused), in the tree's
    // traversal order — deterministic, but not sorted.
    void within(const Eigen::Vector3d& p, double radius, std::vector<int>& out) const;

    [[nodiscard]] int size() const { return static_cast<int>(P_.rows()); }

private:
    struct Node {
        Eigen::Vector3d lo;
        Eigen::Vector3d hi;
        int first = 0;  // leaf: first index into order_; inner: left child (right = first+1)
        int count = 0;  // leaf: number of points; inner: 0
    };
    void build(int node, int first, int count);

    Vertices P_;
    std::vector<int> order_;
    std::vector<Node> nodes_;
};

// The point spacing l_e of §4.2 ("the average distance between the vertices"): the mean over
// points of the mean distance to their 6 nearest other points — the mean edge length a
// triangulation of the points would have (a regular grid of step h gives (4 + 2√2) h / 6 ≈
// 1.14 h, as its triangulated mesh does). 0 for fewer than 7 points.
// `threads`: std::threads; the result does not depend on it.
[[nodiscard]] double mean_point_spacing(const Vertices& points, const KdTree& tree,
                                        int threads = 1);

// Neighbourhoods Ω_i in CSR form (mesh.h): every point within `radius` of point i, and at least
// the `min_count` nearest points where the ball holds fewer (sparse regions of a non-uniform
// sampling). Row i lists i itself first, then the others in ascending index order.
[[nodiscard]] Csr point_neighbourhoods(const Vertices& points,
                                       const KdTree& tree,
                                       double radius,
                                       int min_count,
                                       int threads = 1);

// PCA normals (§4.1, [46]): the eigenvector of the smallest eigenvalue of the covariance of
// each neighbourhood, oriented consistently by propagation along a minimum spanning tree of the
// neighbourhood graph with edge cost 1 − |n_i·n_j| (Hoppe et al. 1992): a normal is flipped to
// agree with its tree parent. Each connected component starts from its point with the largest
// z, whose normal is made to point towards +z (the anterior direction of an OCT surface; for a
// closed surface this is outward, since the top-most point's outward normal has n_z ≥ 0).
// `threads`: std::threads for the per-point PCA; the result does not depend on it.
[[nodiscard]] Vertices pca_normals(const Vertices& points, const Csr& neighbourhoods,
                                   int threads = 1);

// Feature-preserving normals (beyond §4.1; docs/algorithms/pointset.md). PCA over a ball
// blends the two faces within ~r of an edge, and the binary NVT of Eq. 4.2–4.6 keeps that ramp,
// which rounds the edges after the vertex updates. Here ("shifted neighbourhoods") each point
// takes, among the PCA planes of the neighbourhoods Ω_j (j ∈ Ω_i; they contain i) that pass
// within 2.5 σ̂ of it, the flattest one (least λ3 / trace): near an edge that Ω_j lies on one
// face. The plane is then refitted twice to the points of `support` (a wider ball, e.g. 2r)
// within inlier_sigmas × σ̂ of it, which lowers the noise of the normal without blending the
// other face back in. σ̂ is the median RMS distance of the Ω_j to their planes (the noise along
// the normal on a surface that is mostly flat). Orientation: each normal takes the sign of the
// point's consistently oriented PCA normal (pca_normals), which lies within 90° of either face
// at an edge. Throws UsageError unless inlier_sigmas > 0. `threads`: as
// pca_normals.
[[nodiscard]] Vertices shifted_normals(const Vertices& points,
                                         const Csr& neighbourhoods,
                                         const Csr& support,
                                         double inlier_sigmas = 1.0,
                                         int threads = 1);

// The initial normals of the point-set denoiser.
enum class NormalEstimator : std::uint8_t {
    kPca = 0,        // pca_normals (§4.1 as printed)
    kShifted = 1,  // shifted_normals (beyond §4.1: sharper edges)
};

// Feature class of a point (§4.1.2, Eq. 4.10).
enum class PointClass : std::uint8_t { kFlat = 0, kEdge = 1, kCorner = 2 };

// Point-set NVT denoising (§4.1). Each of `iterations` iterations:
//  (1) vertex-based NVT C_i = Σ w_ij n_j n_jᵀ / Σ w_ij over Ω_i (Eq. 4.1) with binary weights
//      w_ij = [∠(n_i, n_j) ≤ ρ] (Eq. 4.2); eigenvalues λ1 ≥ λ2 ≥ λ3 set to 1/0 against τ
//      (binary optimisation, §4.1.1); ñ_i = normalise(d n_i + C̃_i n_i) (Eq. 4.5–4.6);
//  (2) anisotropic covariance A_i of the neighbours with similar filtered normals
//      (Eq. 4.7–4.8), eigenvalues a1 ≥ a2 ≥ a3 divided by r²/2 (the trace of A for a flat disc
//      of radius r, so that τ is dimensionless as in step 1), classes by Eq. 4.10;
//  (3) vertex update: corners by the quadric of Eq. 4.13, edges by the restricted quadric of
//      Eq. 4.15 in the plane normal to the edge, flat points along their normal (Eq. 4.16,
//      weights Eq. 4.17); a point whose new position would lie farther than ε from its input
//      position stays where it is (Eq. 4.11), so max |ṽ_i − v_i| ≤ ε always holds.
// The filtered normals carry over to the next iteration; Ω_i is built once from the input.
struct PointSetParams {
    double tau = 0.3;              // eigenvalue threshold τ (dimensionless), §4.2.1: 0.3–0.4
    double rho = 0.3;              // angle threshold ρ of Eq. 4.2/4.8, radians, in (0, π]
    int iterations = 30;           // p (§4.2.1: 20–100); 0 returns the input unchanged
    double damping = 3.0;          // d of Eq. 4.6; ≥ 0
    double lambda = 0.1;           // λ of Eq. 4.16 (flat-region step), in (0, 1]
    std::optional<double> radius;  // r of Ω_i (length unit); unset: 2 × mean point spacing
    std::optional<double> epsilon; // ε of Eq. 4.11 (length unit); unset: r
    int min_neighbours = 8;        // Ω_i holds at least this many points (incl. i); ≥ 4
    int threads = 1;               // std::threads; results do not depend on it; ≥ 1
    // Initial normals (pca_normals, the default: shifted_normals rounds the cube's edges by
    // half as much but classifies ~1 % fewer points right and tilts a sphere's normals more,
    // docs/algorithms/pointset.md), shifted_normals' refit inlier distance in units of its
    // noise estimate σ̂ (> 0) and its support radius in units of r (≥ 1).
    NormalEstimator normals = NormalEstimator::kPca;
    double inlier_sigmas = 1.0;
    double support = 2.0;
    // Final edge snapping (beyond §4.1, docs/algorithms/pointset.md "Edge snapping"), after the
    // last iteration, for every point whose Ω_i holds an edge or corner point: the reliable
    // points within `snap_support` × r of it (classified flat, with no feature point in their
    // own Ω_j, so ≥ ~1.5 r from an edge) are grouped by their filtered normals (greedy: a normal
    // farther than `snap_group_deg` from every group's mean starts a new group; groups whose
    // means are closer than that are merged; groups with fewer than max(6, 10 %) of the points
    // are dropped, at most 3 kept). With two or more groups, a plane is fitted to each group's
    // denoised positions and the point moves to the nearest point of the piecewise-planar
    // surface they bound — onto the intersection of all planes it lies within `snap_sigmas` ×
    // σ̂ of (σ̂: RMS distance of the groups' input points to their plane), else the nearest
    // plane — unless that is farther than ε from its input position (Eq. 4.11). Points with one
    // group (flat regions, smooth surfaces) do not move. Classes are those of the last
    // iteration.
    bool snap_edges = true;
    double snap_group_deg = 45.0;  // in (0, 90)
    double snap_support = 4.0;     // ball radius in units of r; ≥ 1
    double snap_sigmas = 3.0;      // "within noise" of a plane, in units of σ̂; ≥ 0

    // Throws UsageError naming the first bad field.
    void validate() const;
};

struct PointSetResult {
    Vertices V;                        // #P×3 denoised positions
    Vertices normals;                  // #P×3 filtered unit normals ñ
    std::vector<PointClass> classes;   // #P classes of the last iteration (flat if p = 0)
    int iterations = 0;                // iterations run
    double mean_spacing = 0;           // mean nearest-neighbour distance of the input
    double radius = 0;                 // r used (length unit)
    double epsilon = 0;                // ε used (length unit)
    double mean_neighbourhood = 0;     // mean |Ω_i| (points, incl. i)
    int held_points = 0;               // updates refused by the ε bound, over all iterations
    int snapped_points = 0;            // points moved by the edge snapping (0 if off)
    int corners = 0;                   // points classified corner / edge / flat (last iteration)
    int edges = 0;
    int flats = 0;
    double seconds_setup = 0;          // k-d tree, Ω_i (and the support), initial normals
    double seconds_iterations = 0;     // all iterations
    double seconds_snap = 0;           // the edge snapping
    std::vector<std::string> warnings;
};

// Throws UsageError for bad parameters, DataError for a non-finite point, AnalysisError for
// fewer than 8 points or points that all coincide.
[[nodiscard]] PointSetResult pointset_denoise(const Vertices& points,
                                              const PointSetParams& params = {});

}  // namespace octshape::mesh
