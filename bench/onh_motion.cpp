// ONH parameters on phantoms that move (issue 32): the realistic-acquisition table. For each
// pattern (a full-size volume, 145 x 384; a 24-line radial scan, 384 A-scans per line) of the
// cupped disc, each axial motion SD (default 0, 30, 60, 100 um; a seeded random walk with jumps,
// docs/phantoms.md), with vessel shadows and device-line faults (or without: --no-shadows),
// each ILM source (device, levelset) and registration off / on (docs/algorithms/onh.md, "Axial
// registration"): every parameter's error against the still eye's truth, the estimated shift's
// RMS error against the true shift (the identifiable part: a volume's true shifts minus their
// best cubic in the B-scan position, a radial scan's minus their mean) and the time of the
// registration and of the whole analysis.
// Lateral jitter (volumes; docs/algorithms/onh.md, "Lateral registration"): --jitter 0,10,30
// (SD, um; the lateral registration is on with "on"), --oracle adds a row "true" with the
// phantom's true shifts applied as the registration applies its own, --whole-jitter rounds the
// jitter to whole A-scans and moves the still phantom's B-scans by them (the comparison made for
// the earlier phantom, which blended A-scans; the phantom now renders the moved eye). --bscans/--ascans resize the
// volume, --lat-bscans N caps the lateral cut-off at N B-scans (0 = off), --lat-smoothing SD
// smooths the lines for the lateral estimate (defaults: the ONH's), --spectralis-speckle gives it real Spectralis speckle. --file F (repeatable): the
// lateral shifts estimated on a real scan instead (no truth). --shape swollen|overhang: the swollen
// or the overhanging disc instead of the cupped one; --lines N: radial lines; --on-only: the registered rows alone;
// --residual-only: the still eye's pixels with every line moved by the fractional part of the
// true shift (what the axial registration's whole-row pixel shift leaves between pixels and
// lines, without the phantom's blending of rows), registration off. Level-set variants (volumes,
// for locating an error; docs/algorithms/levelset.md "Overhang volumes"): --ls-window-means
// (classic Chan-Vese window means), --ls-raw (the mesh before RoFi). --eye OD|OS: the eye
// (default OD; OS is the same eye mirrored). Axial oracles (volumes and radial; for locating an
// error): --axial-true applies the phantom's true axial shifts (the whole motion, its cubic in
// the B-scan position too) instead of the estimate; --axial-leave c0,c1,c2,c3 leaves the
// polynomial sum c_j y^j (um, y = -1 at the first B-scan, +1 at the last) in the eye on top of
// --axial-true (+ = deeper), to measure what a smooth motion left in does; --circle-bm F: the
// BM curvature difference k_xx - k_yy of a real circle scan (how far from isotropic the eye
// wall is around the disc); --ls-pixel-frame: the level set's result left in the pixels' frame
// (whole rows; before it was moved by each B-scan's sub-row residual); --free-curvature:
// the axial registration without its isotropic eye wall (every cubic in y left in the eye, the
// registration before issue 32's curvature prior).
// The swollen disc has no cup: its cup column is the cup volume found (1e-3 mm^3, "a").
// --interp-oracle (volumes, the still eye, no registration; docs/algorithms/onh.md "The level
// set's cup-volume deficit, taken apart"): the cup volume of surfaces that differ in one thing
// each (the exact ILM at the nodes, piecewise linear or cubic between B-scans; the device graph;
// the level set; the level set cut at its B-scan planes, linear or cubic between them) and the
// level-set vertices' vertical error by slope; with --ls-mu UM, --ls-despeckle N, --ls-sigma-x UM,
// --ls-patience N the level set's length weight, blur passes, x-blur cap and patience.
// Usage: onh_motion [--motion 0,30,60,100] [--ilm device,levelset] [--pattern volume,radial]
//                   [--shape cupped|swollen|overhang] [--lines N] [--on-only] [--residual-only]
//                   [--no-shadows] [--seed N] [--jitter 0,10,30] [--bscans N] [--ascans N]
//                   [--oracle] [--whole-jitter] [--spectralis-speckle] [--file F]
//                   [--ls-window-means] [--ls-raw] [--lat-bscans N] [--lat-smoothing SD]
//                   [--eye OD|OS] [--axial-true] [--axial-leave c0,c1,c2,c3] [--free-curvature]
//                   [--circle-bm F] [--interp-oracle [--ls-mu UM] [--ls-despeckle N]
//                   [--ls-sigma-x UM] [--ls-patience N]]
//                   [--ls-pixel-frame]

#include <chrono>
#include <cmath>
#include <cstdio>
#include <algorithm>
#include <cstring>
#include <limits>
#include <exception>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "octshape/io/scan_reader.h"
#include "octshape/retina/axial_registration.h"
#include "octshape/retina/levelset.h"
#include "octshape/retina/lateral_registration.h"
#include "octshape/retina/onh.h"
#include "octshape/retina/onh_surfaces.h"
#include "octshape/retina/phantom_onh.h"
#include "fixtures/lateral_shifts.h"

namespace {

using namespace octshape::retina;
using Clock = std::chrono::steady_clock;

std::vector<std::string> split(const std::string& s) {
    std::vector<std::string> out;
    std::stringstream ss(s);
    std::string item;
    while (std::getline(ss, item, ',')) out.push_back(item);
    return out;
}

double pct(double v, double t) { return 100.0 * (v - t) / t; }

// The cup volume's column: % of the truth's, or (the swollen disc has no cup) the volume
// found, in 1e-3 mm^3 ("a" for absolute).
std::string cup_column(double v, double t) {
    char buf[32];
    if (t > 0.0) std::snprintf(buf, sizeof buf, "%+8.2f", pct(v, t));
    else std::snprintf(buf, sizeof buf, "%7.3fa", 1e3 * v);
    return buf;
}

// RMS of (estimated - identifiable true) shifts, um.
double shift_error_um(const AxialRegistration& reg, const std::vector<double>& true_px,
                      double um_per_px, bool radial) {
    const auto n = static_cast<Eigen::Index>(true_px.size());
    const int k = radial ? 1 : 4;
    Eigen::MatrixXd X(n, k);
    Eigen::VectorXd t(n);
    for (Eigen::Index b = 0; b < n; ++b) {
        const double y = n > 1 ? -1.0 + 2.0 * static_cast<double>(b) / static_cast<double>(n - 1) : 0.0;
        for (int j = 0; j < k; ++j) X(b, j) = std::pow(y, j);
        t(b) = true_px[static_cast<std::size_t>(b)] * um_per_px;
    }
    // The difference est - true must be unidentifiable (in the span of X) when the estimate is
    // right: its residual off that span is the error.
    Eigen::VectorXd d(n);
    for (Eigen::Index b = 0; b < n; ++b) d(b) = reg.shift_um[static_cast<std::size_t>(b)] - t(b);
    const Eigen::VectorXd c = X.colPivHouseholderQr().solve(d);
    const Eigen::VectorXd r = d - X * c;
    return std::sqrt(r.squaredNorm() / static_cast<double>(n));
}

// The cubic in y (-1..1 over the B-scans) of true - estimated shifts, um: what a volume's
// registration leaves in the eye.
std::vector<double> left_cubic_um(const AxialRegistration& reg, const std::vector<double>& true_px,
                                  double um_per_px) {
    const auto n = static_cast<Eigen::Index>(true_px.size());
    Eigen::MatrixXd X(n, 4);
    Eigen::VectorXd d(n);
    for (Eigen::Index b = 0; b < n; ++b) {
        const double y = n > 1 ? -1.0 + 2.0 * static_cast<double>(b) / static_cast<double>(n - 1) : 0.0;
        for (int j = 0; j < 4; ++j) X(b, j) = std::pow(y, j);
        d(b) = true_px[static_cast<std::size_t>(b)] * um_per_px - reg.shift_um[static_cast<std::size_t>(b)];
    }
    const Eigen::VectorXd c = X.colPivHouseholderQr().solve(d);
    return {c(0), c(1), c(2), c(3)};
}

// Real circle scans (--circle-bm F): how far from isotropic the eye wall is around the disc.
// A BM depth (1/2) k_xx x^2 + k_xy xy + (1/2) k_yy y^2 on a circle of radius r is, in the angle
// t from the horizontal, r^2 (k_xx + k_yy) / 4 + r^2 (k_xx - k_yy) / 4 cos 2t + r^2 k_xy / 2
// sin 2t: the cos 2t amplitude gives k_xx - k_yy, what the axial registration's isotropic eye
// wall takes as zero (a circle B-scan is one sweep: no motion between its A-scans).
int circle_bm(const std::vector<std::string>& files) {
    std::printf("%-28s %8s %9s %9s %9s %9s %12s %8s %8s\n", "file", "r_mm", "cos2t_um", "sin2t_um", "cos1t_um",
                "sin1t_um", "kxx-kyy um/mm2", "range_um", "res_um");
    for (const std::string& f : files) {
        const octshape::io::Scan scan = octshape::io::read_scan(f);
        const int n = scan.meta.size_x;
        const double r = scan.meta.scale_x_mm * n / (2.0 * M_PI);
        const int bm = static_cast<int>(octshape::io::Layer::kBM);
        std::vector<double> t;
        std::vector<double> d;
        for (int a = 0; a < n; ++a) {
            const float v = scan.depth_px(bm, 0, a);
            if (!octshape::io::is_valid(v)) continue;
            t.push_back(2.0 * M_PI * a / n);
            d.push_back(v * scan.meta.scale_z_mm * 1000.0);
        }
        const auto m = static_cast<Eigen::Index>(t.size());
        Eigen::MatrixXd X(m, 5);
        Eigen::VectorXd y(m);
        for (Eigen::Index i = 0; i < m; ++i) {
            const double ti = t[static_cast<std::size_t>(i)];
            X.row(i) << 1.0, std::cos(ti), std::sin(ti), std::cos(2 * ti), std::sin(2 * ti);
            y(i) = d[static_cast<std::size_t>(i)];
        }
        const Eigen::VectorXd c = X.colPivHouseholderQr().solve(y);
        const std::string name = f.substr(f.find_last_of('/') + 1);
        const double res = std::sqrt((y - X * c).squaredNorm() / static_cast<double>(std::max<Eigen::Index>(1, m)));
        std::printf("%-28s %8.3f %+9.2f %+9.2f %+9.2f %+9.2f %+12.2f %8.1f %8.1f\n", name.c_str(), r, c(3), c(4), c(1), c(2),
                    4.0 * c(3) / (r * r), y.maxCoeff() - y.minCoeff(), res);
    }
    return 0;
}

// Real scans: the lateral shifts the registration estimates (no truth), and the agreement of
// the ILM's and the BM's own estimates.
int real_files(const std::vector<std::string>& files) {
    std::printf("%-44s %5s %6s %7s %6s %8s %8s %7s %8s  %s\n", "file", "nb", "dy_um", "modes",
                "appl", "rms_um", "max_um", "se_um", "res_um", "flags");
    for (const std::string& f : files) {
        const octshape::io::Scan scan = octshape::io::read_scan(f);
        const LateralRegistration lat = estimate_lateral_motion(scan);
        // The same from each line alone (the other one blanked): motion moves both
        // surfaces, so the two estimates agree where the shifts are the eye's motion.
        std::vector<double> alone[2];
        for (int keep = 0; keep < 2; ++keep) {
            octshape::io::Scan one = scan;
            const int drop = keep == 0 ? 1 : 0;  // ILM = 0, BM = 1
            for (auto& bs : one.bscans) {
                if (static_cast<int>(bs.seg.size()) > drop) {
                    for (float& v : bs.seg[static_cast<std::size_t>(drop)]) v = std::numeric_limits<float>::quiet_NaN();
                }
            }
            alone[keep] = estimate_lateral_motion(one).shift_um;
        }
        std::string flags;
        for (const auto& q : lat.qc_flags) flags += "[" + q + "] ";
        const std::string name = f.substr(f.find_last_of('/') + 1);
        std::printf("%-44s %5d %6.1f %7d %6s %8.2f %8.2f %7.2f %8.2f  %s\n", name.c_str(),
                    scan.num_bscans(), scan.meta.distance_mm * 1000.0, lat.smooth_modes,
                    lat.applied ? "yes" : "no", lat.rms_shift_um, lat.max_abs_shift_um,
                    lat.shift_se_um, lat.residual_rms_um, flags.c_str());
        std::printf("  ILM alone vs BM alone: correlation %.3f; ILM alone vs both %.3f\n",
                    octshape::test::correlation(alone[0], alone[1]), octshape::test::correlation(alone[0], lat.shift_um));
    }
    return 0;
}


// --interp-oracle (volumes, the still eye; for locating the level set's cup-volume deficit,
// docs/algorithms/onh.md "Between B-scans"): the cup volume of ILM surfaces that differ in one
// thing each. "truth-nodes": the graph of the exact ILM heights at the scan's nodes (what the
// piecewise-linear surface between B-scans costs alone); "truth-yK": the same with K - 1 exact
// rows between B-scans; "device": the device graph; "device-cubicK": the device heights with
// K - 1 rows between B-scans from the cubic (Catmull-Rom) through the four nearest B-scans
// of the same A-scan; "levelset": the level set. For the level set also its vertices' vertical
// error (vertex height - the true ILM height above it, um; + = towards the vitreous) binned
// by the true slope, on B-scan planes or between them, inside or outside the BMO.
GridSurface refine_rows(const GridSurface& s, int k, const OnhPhantomGeometry* g) {
    GridSurface r;
    r.cols = s.cols;
    r.rows = (s.rows - 1) * k + 1;
    r.dx_mm = s.dx_mm;
    r.dy_mm = s.dy_mm / k;
    r.z.assign(static_cast<std::size_t>(r.cols) * static_cast<std::size_t>(r.rows), 0.0);
    r.filled.assign(r.z.size(), 0);
    for (int j = 0; j < r.rows; ++j) {
        const int b = std::min(j / k, s.rows - 2);
        const double t = static_cast<double>(j - b * k) / k;
        for (int a = 0; a < r.cols; ++a) {
            double z;
            if (g != nullptr) {
                z = g->ilm_heights(a * r.dx_mm, j * r.dy_mm).front();
            } else {
                auto at = [&](int bb) { return s.at(a, std::clamp(bb, 0, s.rows - 1)); };
                const double p0 = at(b - 1), p1 = at(b), p2 = at(b + 1), p3 = at(b + 2);
                // Catmull-Rom: exact for quadratics away from the ends.
                z = p1 + 0.5 * t * (p2 - p0 + t * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 +
                                                   t * (3.0 * (p1 - p2) + p3 - p0)));
            }
            r.z[static_cast<std::size_t>(j) * static_cast<std::size_t>(r.cols) + static_cast<std::size_t>(a)] = z;
        }
    }
    return r;
}

// The top crossing of a mesh at every node (a dx, b dy): the mesh cut by the B-scan plane
// y = b dy, each cut segment sampled at the A-scans it spans, the highest z kept (NaN where
// none): the level set seen on its B-scan planes only.
GridSurface top_at_nodes(const octshape::mesh::Vertices& V, const octshape::mesh::Faces& F, int cols, int rows,
                         double dx, double dy) {
    GridSurface s;
    s.cols = cols;
    s.rows = rows;
    s.dx_mm = dx;
    s.dy_mm = dy;
    s.z.assign(static_cast<std::size_t>(cols) * static_cast<std::size_t>(rows), -std::numeric_limits<double>::infinity());
    s.filled.assign(s.z.size(), 0);
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
        Eigen::Vector3d p[3];
        for (int k = 0; k < 3; ++k) p[k] = V.row(F(f, k)).transpose();
        const double ylo = std::min({p[0].y(), p[1].y(), p[2].y()}), yhi = std::max({p[0].y(), p[1].y(), p[2].y()});
        for (int b = static_cast<int>(std::ceil(ylo / dy - 1e-9)); b <= static_cast<int>(std::floor(yhi / dy + 1e-9)); ++b) {
            if (b < 0 || b >= rows) continue;
            const double yc = b * dy;
            std::vector<Eigen::Vector2d> cut;  // (x, z) where the edges meet the plane
            for (int k = 0; k < 3; ++k) {
                const Eigen::Vector3d& u = p[k];
                const Eigen::Vector3d& v = p[(k + 1) % 3];
                const double du = u.y() - yc, dv = v.y() - yc;
                if (std::abs(du) < 1e-12) cut.emplace_back(u.x(), u.z());
                if ((du < 0 && dv > 0) || (du > 0 && dv < 0)) {
                    const double t = du / (du - dv);
                    cut.emplace_back(u.x() + t * (v.x() - u.x()), u.z() + t * (v.z() - u.z()));
                }
            }
            if (cut.size() < 2) continue;
            std::sort(cut.begin(), cut.end(), [](const Eigen::Vector2d& l, const Eigen::Vector2d& r) { return l.x() < r.x(); });
            const Eigen::Vector2d a0 = cut.front(), a1 = cut.back();
            for (int a = static_cast<int>(std::ceil(a0.x() / dx - 1e-9)); a <= static_cast<int>(std::floor(a1.x() / dx + 1e-9)); ++a) {
                if (a < 0 || a >= cols) continue;
                const double t = a1.x() > a0.x() ? (a * dx - a0.x()) / (a1.x() - a0.x()) : 0.0;
                double& z = s.z[static_cast<std::size_t>(b) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(a)];
                z = std::max(z, a0.y() + t * (a1.y() - a0.y()));
            }
        }
    }
    for (double& z : s.z) {
        if (!std::isfinite(z)) z = std::numeric_limits<double>::quiet_NaN();
    }
    return s;
}

int interp_oracle(const OnhPhantomParams& p, bool shadows, const LevelSetParams& lsp) {
    OnhPhantomParams pm = p;
    pm.artefacts.vessel_shadows = shadows;
    pm.artefacts.segmentation_faults = shadows;
    const OnhTruth truth = compute_onh_truth(pm);
    const octshape::io::Scan scan = render_onh_scan(pm);
    const OnhPhantomGeometry g(pm);
    GridSurface nodes = line_height_field(scan, octshape::io::Layer::kILM);
    for (int b = 0; b < nodes.rows; ++b) {
        for (int a = 0; a < nodes.cols; ++a) {
            nodes.z[static_cast<std::size_t>(b) * static_cast<std::size_t>(nodes.cols) + static_cast<std::size_t>(a)] =
                g.ilm_heights(a * nodes.dx_mm, b * nodes.dy_mm).front();
        }
    }
    auto run = [&](const std::string& name, const IlmSurface& ilm) {
        const OnhResult r = analyse_onh(scan, ilm);
        std::printf("%-16s cup %+7.3f %%  bmoV %+7.3f %%  totV %+7.3f %%  conht %+6.2f um  mrw %+6.2f um  mrwA %+6.2f %%\n",
                    name.c_str(), pct(r.cup_volume_mm3, truth.cup_volume_mm3), pct(r.bmo_volume_mm3, truth.bmo_volume_mm3),
                    pct(r.total_volume_mm3, truth.total_volume_mm3), 1e3 * (r.conht_mm - truth.conht_mm),
                    1e3 * (r.mrw_mean_mm - truth.mrw_mean_mm), pct(r.mrw_area_mm2, truth.mrw_area_mm2));
        return r;
    };
    auto graph = [&](const GridSurface& s) {
        IlmSurface ilm;
        ilm.source = "device";
        graph_mesh(s, ilm.V, ilm.F);
        return ilm;
    };
    std::printf("# %d x %d %s, %s; cup volume %.4f mm^3\n", pm.num_bscans, pm.num_ascans,
                pm.eye == octshape::io::Laterality::kOS ? "OS" : "OD", shadows ? "shadows and faults" : "clean",
                truth.cup_volume_mm3);
    run("truth-nodes", graph(nodes));
    for (int k : {2, 4}) run("truth-y" + std::to_string(k), graph(refine_rows(nodes, k, &g)));
    const IlmSurface dev = build_ilm_surface(scan, IlmSource::kDevice);
    run("device", dev);
    GridSurface ds = line_height_field(scan, octshape::io::Layer::kILM);
    if (std::none_of(ds.z.begin(), ds.z.end(), [](double v) { return std::isnan(v); })) {
        for (int k : {2, 4}) run("device-cubic" + std::to_string(k), graph(refine_rows(ds, k, nullptr)));
    }
    const LevelSetResult ls = levelset_ilm(scan, lsp);
    IlmSurface lsi;
    lsi.V = ls.V;
    lsi.F = ls.F;
    lsi.source = "levelset";
    const OnhResult r = run("levelset", lsi);
    std::printf("  level set: %d iterations, %lld voxel updates, band means c_v %.4f c_t %.4f, level %.4f\n",
                ls.iterations, static_cast<long long>(ls.voxel_updates), ls.c_vitreous, ls.c_tissue,
                0.5 * (ls.c_vitreous + ls.c_tissue));
    for (int raw = 0; raw < 2; ++raw) {
        // The level set on its B-scan planes, as a graph: piecewise linear between them, and the
        // Catmull-Rom cubic with 3 rows between them.
        GridSurface lt = top_at_nodes(raw == 1 ? ls.V_raw : ls.V, ls.F, nodes.cols, nodes.rows, nodes.dx_mm, nodes.dy_mm);
        const auto missing = std::count_if(lt.z.begin(), lt.z.end(), [](double v) { return std::isnan(v); });
        if (missing > 0) thin_plate_fill(lt);
        const std::string tag = raw == 1 ? "ls-raw" : "ls";
        run(tag + "-nodes", graph(lt));
        run(tag + "-nodes-cubic4", graph(refine_rows(lt, 4, nullptr)));
        if (missing > 0) std::printf("  (%ld nodes without a crossing, thin-plate filled)\n", static_cast<long>(missing));
    }
    // Vertical errors of the level-set vertices by region: after RoFi (V) and the marching-cubes
    // vertices before it (V_raw), whose y says whether they lie on a B-scan plane or on an
    // edge between two B-scans.
    const double slopes[] = {0.0, 0.1, 0.3, 0.6, 1.0, 2.0, 1e9};
    std::printf("# level-set vertex height - true ILM height (um), by true slope |grad h|\n");
    std::printf("%-6s %-8s %-8s %-10s %8s %9s %8s\n", "mesh", "where", "plane", "slope", "n", "mean_um", "sd_um");
    for (int raw = 0; raw < 2; ++raw) {
        const auto& V = raw == 1 ? ls.V_raw : ls.V;
        double sum[2][2][6] = {}, sq[2][2][6] = {};
        long cnt[2][2][6] = {};
        for (Eigen::Index i = 0; i < V.rows(); ++i) {
            const double x = V(i, 0), y = V(i, 1), z = V(i, 2);
            const auto h = g.ilm_heights(x, y);
            if (h.size() != 1) continue;  // overhang columns: no single height
            const double e = 1e3 * (z - h.front());
            const double d = 1e-3;
            const double sx = (g.ilm_heights(x + d, y).front() - g.ilm_heights(x - d, y).front()) / (2 * d);
            const double sy = (g.ilm_heights(x, y + d).front() - g.ilm_heights(x, y - d).front()) / (2 * d);
            const double slope = std::hypot(sx, sy);
            const double fy = y / nodes.dy_mm;
            const int on_plane = raw == 0 || std::abs(fy - std::round(fy)) < 1e-6 ? 0 : 1;
            const int inside = g.normalised(x, y).norm() < 1.0 ? 0 : 1;
            int k = 0;
            while (slope >= slopes[k + 1]) ++k;
            sum[inside][on_plane][k] += e;
            sq[inside][on_plane][k] += e * e;
            ++cnt[inside][on_plane][k];
        }
        for (int in = 0; in < 2; ++in) {
            for (int pl = 0; pl < 2; ++pl) {
                for (int k = 0; k < 6; ++k) {
                    const long n = cnt[in][pl][k];
                    if (n == 0) continue;
                    const double m = sum[in][pl][k] / static_cast<double>(n);
                    std::printf("%-6s %-8s %-8s %4.1f-%-5.1f %8ld %+9.2f %8.2f\n", raw == 1 ? "raw" : "rofi",
                                in == 0 ? "in-BMO" : "outside", raw == 0 ? "any" : pl == 0 ? "B-scan" : "between",
                                slopes[k], std::min(slopes[k + 1], 99.0), n, m,
                                std::sqrt(std::max(0.0, sq[in][pl][k] / static_cast<double>(n) - m * m)));
                }
            }
        }
    }
    (void)r;
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    try {
        std::vector<std::string> motions = {"0", "30", "60", "100"};
        std::vector<std::string> ilms = {"device", "levelset"};
        std::vector<std::string> patterns = {"volume", "radial"};
        std::vector<std::string> jitters = {"0"};
        int bscans = 0;  // 0: the preset's
        int ascans = 0;
        int lines = 0;  // 0: the preset's (radial)
        std::string shape = "cupped";
        bool shadows = true;
        bool grain = false;
        bool oracle = false;
        bool whole_jitter = false;
        bool on_only = false;
        bool residual_only = false;
        bool ls_window = false;  // --ls-window-means: classic Chan-Vese window means
        bool ls_raw = false;     // --ls-raw: the level-set mesh before RoFi
        std::uint64_t seed = 1;
        double lat_bscans = -1.0;    // --lat-bscans N: the cut-off capped at N B-scans (0 = off)
        double lat_smoothing = -1.0; // --lat-smoothing SD: the lines smoothed for the estimate
        std::vector<std::string> files;
        std::vector<std::string> circle_files;
        std::string eye = "OD";
        bool axial_true = false;
        bool interp = false;  // --interp-oracle
        LevelSetParams interp_lsp;  // --ls-mu, --ls-despeckle (with --interp-oracle)
        bool ls_pixel_frame = false;
        bool free_curvature = false;  // --free-curvature: the registration before the isotropic prior
        std::vector<double> axial_leave;  // um, coefficients of y^j
        for (int i = 1; i < argc; ++i) {
            const std::string a = argv[i];
            const bool more = i + 1 < argc;
            if (a == "--motion" && more) motions = split(argv[++i]);
            else if (a == "--ilm" && more) ilms = split(argv[++i]);
            else if (a == "--pattern" && more) patterns = split(argv[++i]);
            else if (a == "--jitter" && more) jitters = split(argv[++i]);
            else if (a == "--bscans" && more) bscans = std::stoi(argv[++i]);
            else if (a == "--ascans" && more) ascans = std::stoi(argv[++i]);
            else if (a == "--lines" && more) lines = std::stoi(argv[++i]);
            else if (a == "--shape" && more) shape = argv[++i];
            else if (a == "--no-shadows") shadows = false;
            else if (a == "--file" && more) files.push_back(argv[++i]);
            else if (a == "--circle-bm" && more) circle_files.push_back(argv[++i]);
            else if (a == "--spectralis-speckle") grain = true;
            else if (a == "--oracle") oracle = true;
            else if (a == "--whole-jitter") whole_jitter = true;
            else if (a == "--on-only") on_only = true;
            else if (a == "--residual-only") residual_only = true;
            else if (a == "--ls-window-means") ls_window = true;
            else if (a == "--ls-raw") ls_raw = true;
            else if (a == "--eye" && more) eye = argv[++i];
            else if (a == "--axial-true") axial_true = true;
            else if (a == "--interp-oracle") interp = true;
            else if (a == "--ls-mu" && more) interp_lsp.mu_mm = 1e-3 * std::stod(argv[++i]);
            else if (a == "--ls-despeckle" && more) interp_lsp.despeckle_passes = std::stoi(argv[++i]);
            else if (a == "--ls-sigma-x" && more) interp_lsp.despeckle_max_sigma_x_mm = 1e-3 * std::stod(argv[++i]);
            else if (a == "--ls-patience" && more) interp_lsp.patience = std::stoi(argv[++i]);
            else if (a == "--ls-pixel-frame") ls_pixel_frame = true;
            else if (a == "--free-curvature") free_curvature = true;
            else if (a == "--axial-leave" && more) {
                axial_true = true;
                for (const std::string& c : split(argv[++i])) axial_leave.push_back(std::stod(c));
            }
            else if (a == "--seed" && more) seed = std::stoull(argv[++i]);
            else if (a == "--lat-bscans" && more) lat_bscans = std::stod(argv[++i]);
            else if (a == "--lat-smoothing" && more) lat_smoothing = std::stod(argv[++i]);
            else throw std::runtime_error("unknown argument " + a);
        }
        if (!circle_files.empty()) return circle_bm(circle_files);
        if (!files.empty()) return real_files(files);
        std::printf("# errors against the still eye's truth: volumes, MRW area, bending energy in %%; "
                    "CONHT, MRW (3-D, in-plane) in um; shift err = RMS of estimated - true "
                    "identifiable shift (um)\n");
        std::printf("%-7s %6s %5s %-8s %-4s %8s %8s %8s %8s %8s %8s %7s %8s %8s %8s %9s %7s %7s %6s %7s %7s  %s\n",
                    "pattern", "SD_um", "jit", "ilm", "reg", "cup%", "conht", "bmoV%", "totV%", "annV%",
                    "bmoA%", "mrw", "mrwA%", "bend%", "mrw_ip", "shift_err", "lat_rms", "lat_err", "lat_se", "reg_s", "total_s",
                    "flags");
        for (const std::string& pattern : patterns) {
            if (shape != "cupped" && shape != "swollen" && shape != "overhang") throw std::runtime_error("unknown shape " + shape);
            OnhPhantomParams p = onh_phantom_preset(shape == "overhang" ? OnhShape::kOverhang
                                                    : shape == "swollen" ? OnhShape::kSwollen
                                                                         : OnhShape::kCupped);
            p.radial = pattern == "radial";
            if (lines > 0) p.radial_lines = lines;
            p.seed = seed;
            if (eye == "OS") p.eye = octshape::io::Laterality::kOS;
            else if (eye != "OD") throw std::runtime_error("unknown eye " + eye);
            if (bscans > 0) p.num_bscans = bscans;
            if (ascans > 0) p.num_ascans = ascans;
            if (grain) {
                // Real Spectralis speckle (docs/phantoms.md "Speckle"): 7 looks, grain 1.9 x 1.6 px.
                p.speckle_looks = 7;
                p.speckle_axial_half_width_px = 1.9;
                p.speckle_lateral_half_width_px = 1.6;
            }
            if (interp && !p.radial) {
                interp_oracle(p, shadows, interp_lsp);
                continue;
            }
            const OnhTruth truth = compute_onh_truth(p);
            if (!axial_leave.empty() && !p.radial) {
                // First order (the closest point's envelope): a depth field c(y) left in the eye
                // (+ = deeper, i.e. height -c) moves the MRW at BMO point P, closest ILM point Q,
                // by -v_z (c(y_Q) - c(y_P)), v the unit vector P -> Q.
                const double height = p.field_mm;
                auto c = [&](double y_mm) {
                    const double y = 2.0 * y_mm / height - 1.0;
                    double v = 0.0;
                    for (std::size_t j = 0; j < axial_leave.size(); ++j) v += axial_leave[j] * std::pow(y, static_cast<double>(j));
                    return v;
                };
                double sum = 0.0;
                for (std::size_t i = 0; i < truth.mrw_points_mm.size(); ++i) {
                    const Eigen::Vector3d v = (truth.mrw_points_mm[i] - truth.bmo_points_mm[i]).normalized();
                    sum += -v.z() * (c(truth.mrw_points_mm[i].y()) - c(truth.bmo_points_mm[i].y()));
                }
                std::fprintf(stderr, "first-order MRW change of the polynomial left in: %+.2f um (mean of %zu points)\n",
                             sum / static_cast<double>(truth.mrw_points_mm.size()), truth.mrw_points_mm.size());
            }
            for (const std::string& m : motions) {
              for (const std::string& jit : jitters) {
                OnhPhantomParams pm = p;
                pm.artefacts.motion_sd_um = std::stod(m);
                pm.artefacts.lateral_jitter_um = p.radial ? 0.0 : std::stod(jit);
                pm.artefacts.vessel_shadows = shadows;
                pm.artefacts.segmentation_faults = shadows;
                const auto true_shifts = onh_acquisition_shifts(pm).axial_px;
                auto true_lateral = onh_acquisition_shifts(pm).lateral_px;
                octshape::io::Scan scan0;
                if (whole_jitter && !true_lateral.empty()) {
                    // The jitter rounded to whole A-scans, applied to the phantom without it
                    // (no A-scans blended; the phantom itself renders the moved eye, which
                    // blends none either).
                    OnhPhantomParams ps = pm;
                    ps.artefacts.lateral_jitter_um = 0.0;
                    scan0 = render_onh_scan(ps);
                    for (std::size_t b = 0; b < true_lateral.size(); ++b) {
                        true_lateral[b] = std::round(true_lateral[b]);
                        octshape::io::shift_bscan(scan0.bscans[b], scan0.meta.size_x, scan0.meta.size_z,
                                                  0.0, true_lateral[b]);
                    }
                } else if (residual_only) {
                    // The axial registration's half-pixel residual alone: the still eye's pixels
                    // (no rows blended), every line moved by the fractional part of the true
                    // shift (|r| <= 0.5 px), as the registered lines lie against pixels moved by
                    // whole rows. Run with the registration off (on, it undoes the lines).
                    OnhPhantomParams ps = pm;
                    ps.artefacts.motion_sd_um = 0.0;
                    scan0 = render_onh_scan(ps);
                    for (std::size_t b = 0; b < true_shifts.size(); ++b) {
                        const double r = true_shifts[b] - std::round(true_shifts[b]);
                        std::vector<float> pixels;
                        pixels.swap(scan0.bscans[b].pixels);
                        octshape::io::shift_bscan(scan0.bscans[b], scan0.meta.size_x, scan0.meta.size_z, r);
                        pixels.swap(scan0.bscans[b].pixels);
                    }
                } else {
                    scan0 = render_onh_scan(pm);
                }
                for (const std::string& ilm_name : ilms) {
                    for (const int mode : oracle ? std::vector<int>{0, 1, 2} : on_only ? std::vector<int>{1} : residual_only ? std::vector<int>{0} : std::vector<int>{0, 1}) {
                        const bool reg_on = mode > 0;
                        octshape::io::Scan scan = scan0;
                        const auto t0 = Clock::now();
                        AxialRegistrationParams rp;
                        rp.enabled = reg_on;
                        rp.isotropic_curvature = !free_curvature;
                        LateralRegistrationParams lp = OnhParams{}.lateral_registration;  // the ONH's
                        if (lat_bscans >= 0.0) lp.smooth_wavelength_bscans = lat_bscans;
                        if (lat_smoothing >= 0.0) lp.line_smoothing_ascans = lat_smoothing;
                        lp.enabled = reg_on;
                        LateralRegistration lat = estimate_lateral_motion(scan, lp);
                        if (mode == 2) {
                            // The oracle: the phantom's true shifts, applied as the registration
                            // applies its own (lines fractional, pixels by whole A-scans).
                            lat.applied = true;
                            for (std::size_t b = 0; b < lat.shift_um.size() && b < true_lateral.size(); ++b) {
                                lat.shift_um[b] = true_lateral[b] * scan.meta.scale_x_mm * 1000.0;
                            }
                        }
                        apply_lateral_registration(scan, lat);
                        AxialRegistration reg;
                        if (axial_true && reg_on) {
                            // The oracle: the true shifts (minus what --axial-leave leaves).
                            reg = estimate_axial_motion(scan, rp);
                            const std::size_t n = reg.shift_um.size();
                            for (std::size_t b = 0; b < n && b < true_shifts.size(); ++b) {
                                const double y = n > 1 ? -1.0 + 2.0 * static_cast<double>(b) / static_cast<double>(n - 1) : 0.0;
                                double left = 0.0;
                                for (std::size_t j = 0; j < axial_leave.size(); ++j) left += axial_leave[j] * std::pow(y, static_cast<double>(j));
                                reg.shift_um[b] = true_shifts[b] * scan.meta.scale_z_mm * 1000.0 - left;
                            }
                            reg.applied = true;
                            apply_axial_registration(scan, reg);
                        } else {
                            reg = register_axially(scan, rp);
                        }
                        if (ls_pixel_frame) {
                            // The level set's result left in the pixels' frame (before its
                            // move by the sub-row residual): the lines' offsets forgotten.
                            for (auto& bs : scan.bscans) bs.line_offset_px = 0.0;
                        }
                        const double reg_s = std::chrono::duration<double>(Clock::now() - t0).count();
                        IlmSurface ilm;
                        if ((ls_window || ls_raw) && ilm_name == "levelset" && !p.radial) {
                            // A level-set variant for locating an error (volumes only): its
                            // mesh alone, without the flags and notes build_ilm_surface adds.
                            LevelSetParams lsp;
                            if (ls_window) lsp.region_means = LevelSetParams::RegionMeans::kWindow;
                            const LevelSetResult ls = levelset_ilm(scan, lsp);
                            ilm.V = ls_raw ? ls.V_raw : ls.V;
                            ilm.F = ls.F;
                            ilm.source = "levelset";
                        } else {
                            ilm = build_ilm_surface(scan, ilm_source_from_string(ilm_name));
                        }
                        OnhResult r = analyse_onh(scan, ilm);
                        assess_curvature_mrw_effect(reg, r.ellipse.points_mm, r.mrw_points_mm, rp);
                        const double total_s = std::chrono::duration<double>(Clock::now() - t0).count();
                        std::string flags = "K=" + std::to_string(lat.smooth_modes) +
                                            (lat.applied ? " lat-applied " : " ");
                        for (const auto& f : lat.qc_flags) flags += "[" + f + "] ";
                        for (const auto& f : reg.qc_flags) flags += "[" + f + "] ";
                        for (const auto& f : r.qc_flags) flags += "[" + f + "] ";
                        const double err = shift_error_um(reg, true_shifts, scan.meta.scale_z_mm * 1000.0, p.radial);
                        if (!p.radial && reg_on) {
                            // What the registration left in the eye: the cubic of true - estimated.
                            const auto c = left_cubic_um(reg, true_shifts, scan.meta.scale_z_mm * 1000.0);
                            std::fprintf(stderr, "left in the eye (um, y^0..y^3): %+.2f %+.2f %+.2f %+.2f; curvature to motion %+.2f um, its MRW effect %.2f um\n", c[0], c[1], c[2], c[3], reg.curvature_to_motion_um, reg.curvature_mrw_effect_um);
                        }
                        const double lat_err = octshape::test::identifiable_lateral_error_um(lat, true_lateral, scan.meta.scale_x_mm * 1000.0);
                        std::printf("%-7s %6s %5s %-8s %-4s %8s %+8.1f %+8.2f %+8.2f %+8.2f %+8.2f %+7.1f "
                                    "%+8.2f %+8.2f %+8.1f %9.2f %7.2f %7.2f %6.2f %7.3f %7.2f  %s\n",
                                    pattern.c_str(), m.c_str(), jit.c_str(), ilm_name.c_str(), mode == 2 ? "true" : reg_on ? "on" : "off",
                                    cup_column(r.cup_volume_mm3, truth.cup_volume_mm3).c_str(),
                                    1e3 * (r.conht_mm - truth.conht_mm),
                                    pct(r.bmo_volume_mm3, truth.bmo_volume_mm3),
                                    pct(r.total_volume_mm3, truth.total_volume_mm3),
                                    pct(r.annular_volume_mm3, truth.annular_volume_mm3),
                                    pct(r.ellipse.area_mm2, truth.bmo_area_mm2),
                                    1e3 * (r.mrw_mean_mm - truth.mrw_mean_mm),
                                    pct(r.mrw_area_mm2, truth.mrw_area_mm2),
                                    pct(r.bending_energy, truth.bending_energy),
                                    p.radial ? 1e3 * (r.mrw_inplane_mean_mm - truth.inplane.mean_mm) : 0.0,
                                    err, lat.rms_shift_um, lat_err, lat.shift_se_um, reg_s, total_s, flags.c_str());
                        std::fflush(stdout);
                    }
                }
              }
            }
        }
        return 0;
    } catch (const std::exception& ex) {
        std::fprintf(stderr, "onh_motion: %s\n", ex.what());
        return 1;
    }
}
