#pragma once
// Graph surfaces of the ONH analysis (docs/algorithms/onh.md): a segmentation
// line as a height field on the regular scan grid, its missing values filled by a discrete
// thin-plate (biharmonic) fill, and the field as a triangle mesh in the grid mm frame
// (x = A-scan index * ScaleX, y = B-scan index * Distance, z = -depth * ScaleZ).

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "octshape/io/scan.h"
#include "octshape/mesh/mesh.h"

namespace octshape::retina {

// A height field on the scan grid: node (a, b) is A-scan a of B-scan b, at (a dx, b dy).
struct GridSurface {
    int cols = 0;                      // A-scans per B-scan
    int rows = 0;                      // B-scans
    double dx_mm = 0.0;                // ScaleX
    double dy_mm = 0.0;                // Distance
    std::vector<double> z;             // rows*cols heights (mm), row-major (b * cols + a)
    std::vector<std::uint8_t> filled;  // 1 = the value was missing and has been filled

    [[nodiscard]] double at(int a, int b) const {
        return z[static_cast<std::size_t>(b) * static_cast<std::size_t>(cols) +
                 static_cast<std::size_t>(a)];
    }
    [[nodiscard]] int num_filled() const;
    // Bilinear interpolation at grid mm (x, y); NaN outside [0, (cols-1) dx] x [0, (rows-1) dy]
    // or where a corner of the cell is NaN.
    [[nodiscard]] double bilinear(double x, double y) const;
};

// Heights (mm) of segmentation line `layer` of a volume scan on its grid; missing values NaN,
// nothing filled. Throws AnalysisError if the line is absent.
[[nodiscard]] GridSurface line_height_field(const io::Scan& scan, io::Layer layer);

struct ThinPlateFillResult {
    int filled = 0;         // values filled (NaN before)
    double residual = 0.0;  // max |normal-equation residual| / max |rhs| of the solve
};

// Fills every NaN of `s` (and flags it in s.filled) by minimising the discrete thin-plate
// energy  sum over nodes of z_xx^2 + z_yy^2  +  2 * sum over cells of z_xy^2
// (second differences scaled by the physical spacings) with the present values fixed: the
// discrete biharmonic equation Delta^2 z = 0 on the missing nodes. A quadratic
// z = A x^2 + B xy + C y^2 + D x + E y + F is reproduced exactly on every missing node at least
// two nodes from the grid border (its second differences are constant and every stencil's
// coefficients sum to zero); a harmonic fill cannot do that. Throws AnalysisError
// when fewer than three non-collinear values are present.
ThinPlateFillResult thin_plate_fill(GridSurface& s);

// The height field as a triangle mesh: vertex b*cols + a at (a dx, b dy, z), every cell split
// along its (a, b)-(a+1, b+1) diagonal into two triangles counter-clockwise seen from above
// (normals point up, towards the vitreous; signed projected areas are positive). The field
// must be complete (fill it first): throws AnalysisError on a NaN.
void graph_mesh(const GridSurface& s, mesh::Vertices& V, mesh::Faces& F);

// The same over the cells whose four corners are finite (a field with NaN where nothing was
// scanned, e.g. outside the circle of a radial scan): only vertices of such cells, numbered in
// node order. `node_of_vertex` (optional) receives each vertex's node index b * cols + a.
void graph_mesh_finite(const GridSurface& s, mesh::Vertices& V, mesh::Faces& F,
                       std::vector<int>* node_of_vertex = nullptr);

}  // namespace octshape::retina
