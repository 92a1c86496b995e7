#pragma once
// Fold-overs: two faces sharing an edge that lie (nearly) on top of each other, their normals
// more than ~154° apart. A denoiser's vertex step can push a small face's apex across the
// opposite edge; the face then turns over against its neighbours, which a sharp feature never
// does (docs/algorithms/rofi.md, "Fold-overs"). RoFi and bilateral filtering repair them after
// their last iteration (RofiParams::repair_folds).

#include <cstdint>
#include <vector>

#include "octshape/mesh/mesh.h"

namespace octshape::mesh {

struct FoldRepairParams {
    // Two edge-adjacent faces fold when n_a · n_b < −cos_fold (0.9: 154°; an interior angle
    // below 26° between the faces, sharper than any feature the denoisers keep). In (0, 1].
    double cos_fold = 0.9;
    int max_rounds = 10;  // repair rounds; ≥ 0 (0 = only count)

    // Throws UsageError naming the first bad field.
    void validate() const;
};

struct FoldRepairResult {
    int folds_found = 0;     // folded edges before the first round
    int folds_left = 0;      // folded edges after the last round
    int vertices_moved = 0;  // moves over all rounds (a vertex may move in several)
    int rounds = 0;          // rounds run
};

// Folded edges of (V, F): interior edges whose two faces' normals satisfy n_a · n_b < −cos_fold.
[[nodiscard]] int count_folds(const Vertices& V, const Faces& F, double cos_fold = 0.9);

// Repairs the fold-overs of (V, F) in place. Each round finds the folded edges; of the two
// faces of a fold, the one that agrees less with its other edge-neighbours (n_f · Σ a_h n_h)
// is the turned one, and its corner farthest from the centroid of its own 1-ring (the corner
// that crossed over) moves to that centroid, unless `fixed` (size #V, may be empty) marks it.
// All moves of a round are computed from the round's start (the result does not depend on
// the order of the faces). Stops when no fold is left, nothing can move, or after max_rounds.
// Rigid motions commute with it.
FoldRepairResult repair_folds(Vertices& V,
                              const Faces& F,
                              const std::vector<std::uint8_t>& fixed,
                              const FoldRepairParams& params = {});

// The same with the adjacency of F already built (only vertex_faces and vertex_vertices are
// read; face_faces may have been released), as the denoisers have it.
FoldRepairResult repair_folds(Vertices& V,
                              const Faces& F,
                              const Adjacency& adjacency,
                              const std::vector<std::uint8_t>& fixed,
                              const FoldRepairParams& params = {});

}  // namespace octshape::mesh
