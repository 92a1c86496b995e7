// Acquisition artefacts of the phantoms (docs/phantoms.md, "Acquisition artefacts"): axial eye
// motion and lateral jitter between B-scans, vessel lumens and their shadows, a cleft, and
// device-segmentation faults. They change the B-scans and the device lines, never the eye.

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "octshape/error.h"
#include "octshape/retina/phantom_common.h"

namespace octshape::retina::phantom {
namespace {

void require(bool ok, const std::string& field, const std::string& why) {
    if (!ok) throw UsageError("phantom acquisition: " + field + " " + why);
}

// Rescales `v` to zero mean and standard deviation `sd` (all zeros when it has no spread).
void normalise(std::vector<double>& v, double sd) {
    if (v.empty()) return;
    double mean = 0.0;
    for (double x : v) mean += x;
    mean /= static_cast<double>(v.size());
    double ss = 0.0;
    for (double& x : v) {
        x -= mean;
        ss += x * x;
    }
    const double s = std::sqrt(ss / static_cast<double>(v.size()));
    for (double& x : v) x = s > 0.0 ? x * sd / s : 0.0;
}

// Distance from p to a polyline and the arclength of the closest point from its start.
std::pair<double, double> polyline_distance(const std::vector<Eigen::Vector2d>& line,
                                            const Eigen::Vector2d& p) {
    double best = std::numeric_limits<double>::infinity();
    double at = 0.0;
    double run = 0.0;
    for (std::size_t i = 0; i + 1 < line.size(); ++i) {
        const Eigen::Vector2d ab = line[i + 1] - line[i];
        const double len2 = ab.squaredNorm();
        const double t = len2 > 0.0 ? std::clamp((p - line[i]).dot(ab) / len2, 0.0, 1.0) : 0.0;
        const double d = (p - (line[i] + t * ab)).norm();
        if (d < best) {
            best = d;
            at = run + t * std::sqrt(len2);
        }
        run += std::sqrt(len2);
    }
    return {best, at};
}

// Lumen (brighter, a chord of the round vessel below the ILM) and shadow (the rest of the
// A-scan, attenuated up to 85 % at the vessel's axis) of every A-scan a vessel crosses; the
// cleft: under the first vessel, within its first 0.5 mm, the tissue from the ILM down to
// 0.15 mm (less towards the cleft's edges) as dark as the vitreous.
void draw_vessels(io::Scan& scan,
                  const std::vector<Eigen::Vector2d>& points,
                  const std::vector<VesselPath>& vessels,
                  bool cleft,
                  int ilm_line) {
    const int nx = scan.meta.size_x;
    const int nz = scan.meta.size_z;
    const double sz = scan.meta.scale_z_mm;
    for (int b = 0; b < scan.num_bscans(); ++b) {
        io::BScan& bs = scan.bscans[static_cast<std::size_t>(b)];
        if (bs.pixels.size() != static_cast<std::size_t>(nx) * static_cast<std::size_t>(nz)) continue;
        for (int a = 0; a < nx; ++a) {
            const float ilm = bs.seg[static_cast<std::size_t>(ilm_line)][static_cast<std::size_t>(a)];
            if (!std::isfinite(ilm)) continue;
            const Eigen::Vector2d& g =
                points[static_cast<std::size_t>(b) * static_cast<std::size_t>(nx) +
                       static_cast<std::size_t>(a)];
            double p = 0.0;     // chord fraction of the strongest vessel here
            double width = 0.0;
            double cleft_depth = 0.0;
            for (std::size_t v = 0; v < vessels.size(); ++v) {
                const double half = 0.5 * vessels[v].width_mm;
                const auto [d, along] = polyline_distance(vessels[v].line, g);
                if (d >= half) continue;
                const double q = std::sqrt(1.0 - (d / half) * (d / half));
                if (q > p) {
                    p = q;
                    width = vessels[v].width_mm;
                }
                if (cleft && v == 0 && along < 0.5 && d < half / 1.5) {
                    cleft_depth = 0.15 * (1.0 - d / (half / 1.5));
                }
            }
            if (p <= 0.0) continue;
            const double lumen_top = ilm + 1.0;
            const double lumen_bottom = lumen_top + width * p / sz;
            const double cleft_bottom = ilm + cleft_depth / sz;
            for (int z = static_cast<int>(std::floor(ilm)); z < nz; ++z) {
                float& px = bs.pixels[static_cast<std::size_t>(z) * static_cast<std::size_t>(nx) +
                                      static_cast<std::size_t>(a)];
                const double zz = z;
                if (zz < lumen_top) continue;
                const double gain = zz < lumen_bottom ? 1.0 + 3.0 * p : 1.0 - 0.85 * p;
                px = static_cast<float>(std::min(1.0, px * gain));
                if (zz < cleft_bottom) px *= 0.02F;
            }
        }
    }
}

// The first run of `len` A-scans of B-scan b, searched from `from` in steps of `step`, whose
// grid positions all lie farther than `radius` from `centre`; -1 if none.
int spared_run(const std::vector<Eigen::Vector2d>& points, int nx, int b, int from, int step,
               int len, const Eigen::Vector2d& centre, double radius) {
    for (int a = from; a >= 0 && a + len <= nx; a += step) {
        bool ok = true;
        for (int k = a; k < a + len && ok; ++k) {
            ok = (points[static_cast<std::size_t>(b) * static_cast<std::size_t>(nx) +
                         static_cast<std::size_t>(k)] -
                  centre)
                     .norm() > radius;
        }
        if (ok) return a;
    }
    return -1;
}

}  // namespace

void AcquisitionArtefacts::validate() const {
    require(std::isfinite(motion_sd_um) && motion_sd_um >= 0.0 && motion_sd_um <= 100.0,
            "motion_sd_um", "must be in 0..100");
    require(std::isfinite(lateral_jitter_um) && lateral_jitter_um >= 0.0 &&
                lateral_jitter_um <= 30.0,
            "lateral_jitter_um", "must be in 0..30");
}

AcquisitionShifts acquisition_shifts(const AcquisitionArtefacts& artefacts,
                                     int num_bscans,
                                     double scale_z_mm,
                                     double scale_x_mm,
                                     bool radial,
                                     std::uint64_t seed) {
    const auto nb = static_cast<std::size_t>(std::max(0, num_bscans));
    AcquisitionShifts s;
    s.axial_px.assign(nb, 0.0);
    s.lateral_px.assign(nb, 0.0);
    if (nb < 2) return s;
    if (artefacts.motion_sd_um > 0.0) {
        // A random walk (slow drift: heartbeat, breathing) with a jump in 8 % of the steps
        // (a saccade or a head movement), four times a step's size.
        Rng rng(seed, 0xA0710EULL);
        for (std::size_t b = 1; b < nb; ++b) {
            const double jump = rng.uniform() < 0.08 ? 4.0 * rng.normal() : 0.0;
            s.axial_px[b] = s.axial_px[b - 1] + rng.normal() + jump;
        }
        normalise(s.axial_px, artefacts.motion_sd_um * 1e-3 / scale_z_mm);
    }
    if (artefacts.lateral_jitter_um > 0.0 && !radial) {
        Rng rng(seed, 0x1A7E2AULL);
        for (double& x : s.lateral_px) x = rng.normal();
        normalise(s.lateral_px, artefacts.lateral_jitter_um * 1e-3 / scale_x_mm);
    }
    return s;
}

std::vector<Eigen::Vector2d> acquired_points(const std::vector<Eigen::Vector2d>& points,
                                             int size_x,
                                             const AcquisitionShifts& shifts) {
    std::vector<Eigen::Vector2d> out = points;
    const auto nx = static_cast<std::size_t>(std::max(0, size_x));
    if (nx < 2) return out;
    for (std::size_t b = 0; b < shifts.lateral_px.size() && (b + 1) * nx <= out.size(); ++b) {
        const double dx = shifts.lateral_px[b];
        if (dx == 0.0) continue;
        const Eigen::Vector2d step = points[b * nx + 1] - points[b * nx];
        for (std::size_t a = 0; a < nx; ++a) out[b * nx + a] -= dx * step;
    }
    return out;
}

void apply_acquisition_artefacts(io::Scan& scan,
                                 const std::vector<Eigen::Vector2d>& points,
                                 const std::vector<VesselPath>& vessels,
                                 const AcquisitionArtefacts& artefacts,
                                 int ilm_line,
                                 int bm_line,
                                 const Eigen::Vector2d& spare_centre_mm,
                                 double spare_radius_mm) {
    const int nx = scan.meta.size_x;
    const int nz = scan.meta.size_z;
    const int nb = scan.num_bscans();
    // The moved retina must stay in the image (checked on its lines, before any fault).
    for (int b = 0; b < nb; ++b) {
        const io::BScan& bs = scan.bscans[static_cast<std::size_t>(b)];
        float top = std::numeric_limits<float>::infinity();
        float bottom = -std::numeric_limits<float>::infinity();
        for (int k : {ilm_line, bm_line}) {
            for (float v : bs.seg[static_cast<std::size_t>(k)]) {
                if (!std::isfinite(v)) continue;
                top = std::min(top, v);
                bottom = std::max(bottom, v);
            }
        }
        require(!std::isfinite(top) || (top >= 1.0 && bottom <= nz - 10.0),
                "motion_sd_um",
                "moves the retina of B-scan " + std::to_string(b) +
                    " out of the image: use a larger depth or less motion");
    }
    if ((artefacts.vessel_shadows || artefacts.cleft) && !vessels.empty()) {
        draw_vessels(scan, points, artefacts.vessel_shadows ? vessels
                                                             : std::vector<VesselPath>{vessels.front()},
                     artefacts.cleft, ilm_line);
    }
    if (artefacts.segmentation_faults) {
        // An ILM spike: 4 A-scans of B-scan nb/4 reported 25 px (97 um) too high.
        const int b_spike = nb / 4;
        const int a_spike = spared_run(points, nx, b_spike, nx / 20, 1, 4, spare_centre_mm,
                                       spare_radius_mm);
        if (a_spike >= 0) {
            auto& line = scan.bscans[static_cast<std::size_t>(b_spike)].seg[static_cast<std::size_t>(ilm_line)];
            for (int a = a_spike; a < a_spike + 4; ++a) {
                float& v = line[static_cast<std::size_t>(a)];
                v = std::max(0.0F, v - 25.0F);
            }
        }
        // A BM gap: nx/16 A-scans of B-scan 3 nb/4 missing.
        const int b_gap = (3 * nb) / 4;
        const int len = std::max(2, nx / 16);
        const int a_gap = spared_run(points, nx, b_gap, nx - nx / 20 - len, -1, len,
                                     spare_centre_mm, spare_radius_mm);
        if (a_gap >= 0) {
            auto& line = scan.bscans[static_cast<std::size_t>(b_gap)].seg[static_cast<std::size_t>(bm_line)];
            for (int a = a_gap; a < a_gap + len; ++a) {
                line[static_cast<std::size_t>(a)] = std::numeric_limits<float>::quiet_NaN();
            }
        }
    }
}

}  // namespace octshape::retina::phantom
