// Lateral registration on macular volumes (issue 32; docs/algorithms/cube.md, "Lateral
// registration"). Two parts.
//
// Phantoms (default): the macula phantom (Bezier family, --scheibe / --flat for the others) at
// --bscans x --ascans (default 61 x 768), with lateral jitter --jitter (SD um, default 0,10,30),
// segmentation noise --noise (px per surface, default 0,1) and axial motion --motion (SD um,
// default 0,30), over --seeds N seeds; the registration's estimate against the phantom's true
// shifts (lat_err: RMS of estimated - true without the first K cosines across the B-scans, the
// part a smooth eye cannot tell from smooth motion; false_um: the estimate's RMS on the same eye
// without jitter) and every CuBe parameter with the registration off / on / the true shifts
// ("true", applied as the registration applies its own) against the still scan of the same seed
// (same noise), % (CFT and rim height in um). --wavelength W1,W2 (mm): the smooth cut-off.
//
// Real cubes (--file F, repeatable; no truth): the estimate from ILM + BM, from the ILM alone and
// from the BM alone (their correlation), and evidence that does not come from the estimate:
// the roughness across B-scans (robust SD of the second difference across B-scans, each B-scan
// triple's median removed, which cancels the axial motion) of every line held out of the
// estimate, before and after; the BM's roughness after the ILM-alone shifts and the ILM's after
// the BM-alone shifts (cross-validation); the same for shifts of the same size in a random order
// (a control: what shifts that are not the motion do); the fovea's position per B-scan (the
// thickness minimum's A-scan near the centre) and its jumps; and how much the CuBe parameters and
// the ETDRS sector thicknesses move when the scan is registered.
// Usage: macula_motion [--bscans N] [--ascans N] [--jitter 0,10,30] [--noise 0,1]
//                      [--motion 0,30] [--seeds N] [--wavelength 0.75] [--scheibe] [--flat]
//                      [--fovea-dx MM] [--fovea-dy MM] [--dx-mm MM] [--dy-mm MM]
//                      [--smooth 0,4 (default: the macula's, 4)] [--whole-jitter]
//                      [--wavelength-bscans B (default: the macula's, 8; 0 = off)] [--file F]

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "octshape/io/scan_reader.h"
#include "octshape/retina/cube.h"
#include "octshape/retina/etdrs.h"
#include "octshape/retina/lateral_registration.h"
#include "octshape/retina/phantom_macula.h"
#include "fixtures/lateral_shifts.h"

namespace {

using namespace octshape::retina;
namespace io = octshape::io;

// --wavelength-bscans (default: the macula analysis's cap, CubeParams).
double g_wavelength_bscans = CubeParams{}.lateral_registration.smooth_wavelength_bscans;

std::vector<double> split(const std::string& s) {
    std::vector<double> out;
    std::stringstream ss(s);
    std::string item;
    while (std::getline(ss, item, ',')) out.push_back(std::stod(item));
    return out;
}

double pct(double v, double ref) { return 100.0 * (v / ref - 1.0); }

void print_cube_row(const char* label, const CubeResult& r, const CubeResult& ref) {
    std::printf("  %-5s cft %+6.2f um  rimH %+6.2f um  rimD %+6.2f%%  rimA %+6.2f%%  rimV %+6.2f%%  "
                "innerV %+6.2f%%  pitV %+6.2f%%  slope %+6.2f%%  slopeA %+6.2f%%  flatA %+6.2f%%\n",
                label, 1e3 * (r.cft_mm - ref.cft_mm), 1e3 * (r.rim_height_mm - ref.rim_height_mm),
                pct(r.rim.diameter_mm, ref.rim.diameter_mm), pct(r.rim.area_mm2, ref.rim.area_mm2),
                pct(r.rim_volume_mm3, ref.rim_volume_mm3),
                pct(r.inner_rim_volume_mm3, ref.inner_rim_volume_mm3),
                pct(r.pit_volume_mm3, ref.pit_volume_mm3),
                pct(r.max_pit_slope_deg, ref.max_pit_slope_deg),
                pct(r.slope.area_mm2, ref.slope.area_mm2),
                pct(r.pit_flat.area_mm2, ref.pit_flat.area_mm2));
}

double corr(const std::vector<double>& x, const std::vector<double>& y) {
    return octshape::test::correlation(x, y);
}

// The shifts estimated from the ILM alone (keep 0) or the BM alone (keep 1), the other line
// blanked.
std::vector<double> alone_estimate(const io::Scan& scan, int keep, const LateralRegistrationParams& lp) {
    io::Scan one;
    one.meta = scan.meta;
    one.bscans.resize(scan.bscans.size());
    for (std::size_t b = 0; b < scan.bscans.size(); ++b) {
        one.bscans[b].seg = scan.bscans[b].seg;
        for (float& v : one.bscans[b].seg[static_cast<std::size_t>(keep == 0 ? 1 : 0)]) {
            v = std::numeric_limits<float>::quiet_NaN();
        }
    }
    return estimate_lateral_motion(one, lp).shift_um;
}

int phantoms(const MaculaPhantomParams& base, const std::vector<double>& jitters,
             const std::vector<double>& noises, const std::vector<double>& motions, int seeds,
             const std::vector<double>& wavelengths, const std::vector<double>& smoothings,
             bool whole_jitter) {
    std::printf("# macula phantom %d x %d, %s%s; errors against the still scan of the same seed\n",
                base.num_bscans, base.size_x, to_string(base.family).c_str(), base.flat ? " flat" : "");
    for (double wl : wavelengths) {
      for (double sm : smoothings) {
        for (double noise : noises) {
            for (double motion : motions) {
                for (double jit : jitters) {
                    for (int seed = 1; seed <= seeds; ++seed) {
                        MaculaPhantomParams p = base;
                        p.pixels = false;
                        p.seed = static_cast<std::uint64_t>(seed);
                        p.noise_um = noise * p.scale_z_mm * 1000.0;
                        MaculaPhantomParams still_p = p;
                        p.artefacts.lateral_jitter_um = jit;
                        p.artefacts.motion_sd_um = motion;
                        const io::Scan still = make_macula_phantom(still_p).scan;
                        std::vector<double> truth_px = macula_acquisition_shifts(p).lateral_px;
                        io::Scan moved;
                        if (whole_jitter) {
                            // The jitter in whole A-scans on the phantom without it: no A-scans
                            // blended, the noise of every value kept (a device samples).
                            MaculaPhantomParams q = p;
                            q.artefacts.lateral_jitter_um = 0.0;
                            moved = make_macula_phantom(q).scan;
                            for (std::size_t b = 0; b < truth_px.size(); ++b) {
                                truth_px[b] = std::round(truth_px[b]);
                                io::shift_bscan(moved.bscans[b], moved.meta.size_x, moved.meta.size_z, 0.0, truth_px[b]);
                            }
                        } else {
                            moved = make_macula_phantom(p).scan;
                        }
                        LateralRegistrationParams lp = CubeParams{}.lateral_registration;
                        lp.smooth_wavelength_bscans = g_wavelength_bscans;
                        lp.smooth_wavelength_mm = wl;
                        lp.line_smoothing_ascans = sm;
                        const LateralRegistration still_reg = estimate_lateral_motion(still, lp);
                        const LateralRegistration reg = estimate_lateral_motion(moved, lp);
                        const double um_x = moved.meta.scale_x_mm * 1000.0;
                        const double c_alone = corr(alone_estimate(moved, 0, lp), alone_estimate(moved, 1, lp));
                        std::printf("sm %.1f wl %.2f noise %.1f px motion %3.0f jitter %3.0f seed %d: K %d  "
                                    "still: rms %.2f max %.2f applied %d | moved: rms %.2f se %.2f "
                                    "lat_err %.2f um applied %d res %.2f flags %zu corr_alone %.3f\n",
                                    sm, wl, noise, motion, jit, seed, reg.smooth_modes,
                                    still_reg.rms_shift_um, still_reg.max_abs_shift_um,
                                    still_reg.applied ? 1 : 0, reg.rms_shift_um, reg.shift_se_um,
                                    octshape::test::identifiable_lateral_error_um(reg, truth_px, um_x), reg.applied ? 1 : 0,
                                    reg.residual_rms_um, reg.qc_flags.size(), c_alone);
                        const CubeResult ref = analyse_macula(still);
                        const CubeResult off = analyse_macula(moved);
                        io::Scan on_scan = moved;
                        apply_lateral_registration(on_scan, reg);
                        const CubeResult on = analyse_macula(on_scan);
                        LateralRegistration t = reg;
                        t.applied = true;
                        for (std::size_t b = 0; b < t.shift_um.size(); ++b) t.shift_um[b] = truth_px[b] * um_x;
                        io::Scan true_scan = moved;
                        apply_lateral_registration(true_scan, t);
                        const CubeResult tr = analyse_macula(true_scan);
                        if (jit > 0.0 || motion > 0.0) {
                            print_cube_row("off", off, ref);
                            print_cube_row("on", on, ref);
                            print_cube_row("true", tr, ref);
                        }
                        std::fflush(stdout);
                    }
                }
            }
        }
      }
    }
    return 0;
}

// ---- real cubes ----

std::vector<double> to_px(const std::vector<double>& um, double um_per_ascan) {
    std::vector<double> out(um.size());
    for (std::size_t i = 0; i < um.size(); ++i) out[i] = um[i] / um_per_ascan;
    return out;
}

// The fovea's A-scan in each B-scan within +-rows of the centre B-scan: the minimum of the
// thickness (ILM - BM, smoothed over +-3 A-scans) within +-window A-scans of the centre A-scan.
std::vector<double> fovea_track(const io::Scan& scan, int centre_b, int centre_a, int rows,
                                int window, const std::vector<double>& shift_px) {
    std::vector<double> out;
    for (int b = centre_b - rows; b <= centre_b + rows; ++b) {
        if (b < 0 || b >= scan.num_bscans()) continue;
        const auto& bs = scan.bscans[static_cast<std::size_t>(b)];
        double best = std::numeric_limits<double>::infinity();
        double at = std::numeric_limits<double>::quiet_NaN();
        for (int a = centre_a - window; a <= centre_a + window; ++a) {
            double sum = 0.0;
            int n = 0;
            for (int d = -3; d <= 3; ++d) {
                const double x = a + d + shift_px[static_cast<std::size_t>(b)];
                const double t = octshape::test::line_at(bs.seg[1], x) - octshape::test::line_at(bs.seg[0], x);
                if (std::isfinite(t)) { sum += t; ++n; }
            }
            if (n == 7 && sum < best) { best = sum; at = a; }
        }
        out.push_back(at);
    }
    return out;
}

double rms_jump(const std::vector<double>& t) {
    double s = 0.0;
    int n = 0;
    for (std::size_t i = 1; i < t.size(); ++i) {
        if (std::isfinite(t[i]) && std::isfinite(t[i - 1])) { s += (t[i] - t[i - 1]) * (t[i] - t[i - 1]); ++n; }
    }
    return n ? std::sqrt(s / n) : 0.0;
}

int real_files(const std::vector<std::string>& files, double smoothing, double wavelength) {
    LateralRegistrationParams lp = CubeParams{}.lateral_registration;
    lp.smooth_wavelength_bscans = g_wavelength_bscans;
    lp.line_smoothing_ascans = smoothing;
    lp.smooth_wavelength_mm = wavelength;
    for (const std::string& f : files) {
        const io::Scan scan = io::read_scan(f);
        const std::string name = f.substr(f.find_last_of('/') + 1);
        const double um_x = scan.meta.scale_x_mm * 1000.0;
        const LateralRegistration both = estimate_lateral_motion(scan, lp);
        const std::vector<double> alone[2] = {alone_estimate(scan, 0, lp), alone_estimate(scan, 1, lp)};
        std::printf("%s: %d x %d, dx %.1f um, dy %.1f um, K %d; RMS %.2f um, largest %.2f, SE %.2f, "
                    "applied %d\n", name.c_str(), scan.num_bscans(), scan.meta.size_x, um_x,
                    scan.meta.distance_mm * 1000.0, both.smooth_modes, both.rms_shift_um,
                    both.max_abs_shift_um, both.shift_se_um, both.applied ? 1 : 0);
        std::printf("  correlation ILM-alone vs BM-alone %.3f, ILM-alone vs both %.3f, BM-alone vs both %.3f\n",
                    corr(alone[0], alone[1]), corr(alone[0], both.shift_um), corr(alone[1], both.shift_um));
        const std::vector<double> zero(static_cast<std::size_t>(scan.num_bscans()), 0.0);
        const std::vector<double> s_both = to_px(both.shift_um, um_x);
        const std::vector<double> s_ilm = to_px(alone[0], um_x);
        const std::vector<double> s_bm = to_px(alone[1], um_x);
        // The control: the same shifts in a random order (same size, not the motion).
        std::vector<double> s_perm = s_both;
        std::mt19937 rng(7);
        std::shuffle(s_perm.begin(), s_perm.end(), rng);
        std::printf("  roughness across B-scans (px): line  none  ILM+BM  ILM-alone  BM-alone  permuted\n");
        int nlines = 0;
        for (const auto& bs : scan.bscans) nlines = std::max(nlines, static_cast<int>(bs.seg.size()));
        for (int k = 0; k < nlines; ++k) {
            const double r0 = octshape::test::lateral_roughness_px(scan, k, zero);
            if (!std::isfinite(r0)) continue;
            std::printf("    %-10s %6.3f %6.3f %6.3f %6.3f %6.3f%s\n", scan.line_name(k).c_str(), r0,
                        octshape::test::lateral_roughness_px(scan, k, s_both), octshape::test::lateral_roughness_px(scan, k, s_ilm),
                        octshape::test::lateral_roughness_px(scan, k, s_bm), octshape::test::lateral_roughness_px(scan, k, s_perm),
                        k == 0 ? "  (ILM: in the estimate except BM-alone)" : k == 1 ? "  (BM: in the estimate except ILM-alone)" : "  (held out)");
        }
        // Calibration: the held-out lines' mean roughness with the shifts scaled (a right
        // estimate is smoothest near 1; an estimate that is half noise near 0.5).
        std::printf("  held-out roughness vs scale of the ILM+BM shifts:");
        for (double fac : {0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5}) {
            std::vector<double> sc = s_both;
            for (double& v : sc) v *= fac;
            double sum = 0.0;
            int n = 0;
            for (int k = 2; k < nlines; ++k) {
                const double r = octshape::test::lateral_roughness_px(scan, k, sc);
                if (std::isfinite(r)) { sum += r; ++n; }
            }
            std::printf(" %.2f:%.4f", fac, n ? sum / n : 0.0);
        }
        std::printf("\n");
        // CuBe and ETDRS, unregistered and registered.
        const CubeResult off = analyse_macula(scan);
        io::Scan reg_scan = scan;
        LateralRegistration applied = both;
        applied.applied = true;  // whatever the floor: what registration would change
        apply_lateral_registration(reg_scan, applied);
        const CubeResult on = analyse_macula(reg_scan);
        const int cb = static_cast<int>(std::lround(off.centre_mm.y() / scan.meta.distance_mm));
        const int ca = static_cast<int>(std::lround(off.centre_mm.x() / scan.meta.scale_x_mm));
        const int rows = static_cast<int>(std::ceil(0.3 / scan.meta.distance_mm));
        const int win = static_cast<int>(std::ceil(0.25 / scan.meta.scale_x_mm));
        std::printf("  fovea track (thickness minimum's A-scan, B-scans +-%d of %d, +-%d A-scans): RMS jump "
                    "between B-scans %.2f A-scans unregistered, %.2f registered, %.2f permuted\n",
                    rows, cb, win, rms_jump(fovea_track(scan, cb, ca, rows, win, zero)),
                    rms_jump(fovea_track(scan, cb, ca, rows, win, s_both)),
                    rms_jump(fovea_track(scan, cb, ca, rows, win, s_perm)));
        std::printf("  centre moved by (%.1f, %.1f) um\n", 1e3 * (on.centre_mm.x() - off.centre_mm.x()),
                    1e3 * (on.centre_mm.y() - off.centre_mm.y()));
        print_cube_row("reg", on, off);
        std::printf("    unregistered: cft %.1f um rimH %.1f um rimD %.3f mm rimA %.3f mm2 rimV %.4f mm3 flatA %.4f mm2 rmse %.2f um\n",
                    1e3 * off.cft_mm, 1e3 * off.rim_height_mm, off.rim.diameter_mm, off.rim.area_mm2,
                    off.rim_volume_mm3, off.pit_flat.area_mm2, off.rmse_um);
        std::printf("    registered:   rmse %.2f um\n", on.rmse_um);
        const EtdrsReport e_off = etdrs_report(scan, off);
        const EtdrsReport e_on = etdrs_report(reg_scan, on);
        if (e_off.at_fovea && e_on.at_fovea) {
            std::printf("  ETDRS at the fovea, registered - unregistered (um):");
            for (std::size_t s = 0; s < kEtdrsSectors; ++s) {
                std::printf(" %+.2f", 1e3 * (e_on.at_fovea->sectors[s].thickness_mm - e_off.at_fovea->sectors[s].thickness_mm));
            }
            std::printf("  (of %.1f..%.1f um)\n", 1e3 * e_off.at_fovea->sectors[0].thickness_mm,
                        1e3 * e_off.at_fovea->sectors[5].thickness_mm);
        }
        if (e_off.at_scan_centre && e_on.at_scan_centre) {
            std::printf("  ETDRS at the scan centre, registered - unregistered (um):");
            for (std::size_t s = 0; s < kEtdrsSectors; ++s) {
                std::printf(" %+.2f", 1e3 * (e_on.at_scan_centre->sectors[s].thickness_mm - e_off.at_scan_centre->sectors[s].thickness_mm));
            }
            std::printf("\n");
        }
        std::printf("  shifts (um):");
        for (double s : both.shift_um) std::printf(" %.0f", s);
        std::printf("\n");
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    try {
        MaculaPhantomParams p;
        std::vector<double> jitters = {0, 10, 30};
        std::vector<double> noises = {0, 1};
        std::vector<double> motions = {0, 30};
        std::vector<double> wavelengths = {0.75};
        // The macula analysis's smoothing by default (CubeParams).
        std::vector<double> smoothings = {CubeParams{}.lateral_registration.line_smoothing_ascans};
        bool whole_jitter = false;
        int seeds = 1;
        std::vector<std::string> files;
        for (int i = 1; i < argc; ++i) {
            const std::string a = argv[i];
            const bool more = i + 1 < argc;
            if (a == "--bscans" && more) p.num_bscans = std::stoi(argv[++i]);
            else if (a == "--ascans" && more) p.size_x = std::stoi(argv[++i]);
            else if (a == "--jitter" && more) jitters = split(argv[++i]);
            else if (a == "--noise" && more) noises = split(argv[++i]);
            else if (a == "--motion" && more) motions = split(argv[++i]);
            else if (a == "--wavelength" && more) wavelengths = split(argv[++i]);
            else if (a == "--seeds" && more) seeds = std::stoi(argv[++i]);
            else if (a == "--smooth" && more) smoothings = split(argv[++i]);
            else if (a == "--whole-jitter") whole_jitter = true;
            else if (a == "--wavelength-bscans" && more) g_wavelength_bscans = std::stod(argv[++i]);
            else if (a == "--dx-mm" && more) p.scale_x_mm = std::stod(argv[++i]);
            else if (a == "--dy-mm" && more) p.distance_mm = std::stod(argv[++i]);
            else if (a == "--scheibe") p.family = MaculaFamily::kScheibe;
            else if (a == "--flat") p.flat = true;
            else if (a == "--fovea-dx" && more) p.fovea_dx_mm = std::stod(argv[++i]);
            else if (a == "--fovea-dy" && more) p.fovea_dy_mm = std::stod(argv[++i]);
            else if (a == "--file" && more) files.push_back(argv[++i]);
            else throw std::runtime_error("unknown argument " + a);
        }
        if (!files.empty()) return real_files(files, smoothings.front(), wavelengths.front());
        return phantoms(p, jitters, noises, motions, seeds, wavelengths, smoothings, whole_jitter);
    } catch (const std::exception& ex) {
        std::fprintf(stderr, "macula_motion: %s\n", ex.what());
        return 1;
    }
}
