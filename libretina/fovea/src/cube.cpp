// CuBe fovea analysis (thesis §7.1-7.3, docs/algorithms/cube.md): the driver and its fitting
// stages. The stages and what they hand each other: cube_stages.h; decisions:
// docs/algorithms/cube.md.

#include "octshape/retina/cube.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "cube_stages.h"
#include "octshape/error.h"
#include "octshape/retina/radial_geometry.h"
#include "octshape/retina/scan_geometry.h"
#include "octshape/retina/scan_limits.h"

namespace octshape::retina {
using namespace cube_detail;
namespace {

bool is_volume(const io::Scan& scan) {
    const auto pat = scan.meta.pattern;
    if (is_radial_scan(scan)) return false;
    return pat == io::ScanPattern::kVolume || pat == io::ScanPattern::kFastVolume ||
           (pat == io::ScanPattern::kUnknown && scan.num_bscans() > 1);
}

}  // namespace

namespace cube_detail {

bool check_macula_scan(const io::Scan& scan) {
    bool line_scan = false;
    const auto pat = scan.meta.pattern;
    if (pat == io::ScanPattern::kLine) {
        if (scan.num_bscans() != 1) {
            throw AnalysisError("line scan with " + std::to_string(scan.num_bscans()) +
                                " B-scans: expected exactly one B-scan through the fovea");
        }
        line_scan = true;
    } else if (!is_volume(scan)) {
        throw AnalysisError("scan pattern '" + std::string(io::to_string(pat)) +
                            "' cannot be analysed as a macula: a volume scan or a single line "
                            "through the fovea is needed");
    }
    if (!line_scan && !(scan.meta.distance_mm > 0.0)) {
        throw AnalysisError("volume scan without a B-scan distance in its header");
    }
    if (!(scan.meta.scale_x_mm > 0.0) || !(scan.meta.scale_z_mm > 0.0)) {
        throw AnalysisError("the scan's ScaleX/ScaleZ are not positive");
    }
    // Before anything is allocated from them (samples per half-line, kernel widths).
    check_scan_scales(scan, !line_scan);
    return line_scan;
}

void take_centre(CubeResult& res, Centre&& centre) {
    res.search_centre_mm = centre.search_centre_mm;
    res.centre_source = std::move(centre.source);
    res.centre_mm = centre.centre_mm;
    res.cft_mm = centre.cft_mm;
    res.num_tied_minima = centre.num_tied_minima;
    res.centre_fit_radius_mm = centre.fit_radius_mm;
    res.notes = std::move(centre.notes);
    res.qc_flags = std::move(centre.qc_flags);
}

void fit_half_lines(CubeResult& res, RadialSamples& samples, double centre_sample_mm,
                    const CubeParams& params, double crest_mm) {
    // CFT as a model estimate (docs/algorithms/cube.md "CFT"): every interior fitted with its
    // start height free; CFT = the mean of those heights (the shared P0.y of Eq. 7.5); then
    // every half-line fitted with P0 = (0, CFT) as the thesis' model has it.
    res.cft_sample_mm = res.cft_mm;
    const CftPass cft = cft_pass(samples.half_lines, centre_sample_mm, res.cft_mm, params, crest_mm);
    res.cft_mm = cft.cft_mm;
    final_fit(samples, cft, params, crest_mm);
    res.half_lines = std::move(samples.half_lines);
}

CftPass cft_pass(const std::vector<CubeHalfLine>& lines,
                 double centre_sample_mm,
                 double cft_sample_mm,
                 const CubeParams& params,
                 double crest_mm) {
    // The CFT pass only feeds P0.y into a mean: a relative energy change of 1e-6 leaves CFT
    // within 0.01 um of the 1e-10 result (12 noisy 193-B-scan phantoms) at ~60 % of the
    // rounds; the final pass, warm-started from this one, keeps the 1e-10 of
    // docs/algorithms/cube.md step 5.
    constexpr double kCftPassTolerance = 1e-6;
    const FitSettings free_fs{
        .max_rounds = params.max_rounds,
        .energy_tolerance = std::max(kCftPassTolerance, params.energy_tolerance),
        .free_start_height = true,
        .rim_point = params.rim_point,
        .crest_tolerance_mm = crest_mm};
    CftPass out;
    out.cft_mm = cft_sample_mm;
    out.free_fits.reserve(lines.size());
    double sum = 0.0;
    int count = 0;
    // Every half-line's first sample is the centre: under noise the bilinear M there (4
    // nodes, 2-4 um of noise) entered all 24 fits alike, an error no mean removes; a quadratic
    // surface over half the centre window averages the nodes of its window instead (at least
    // 3 B-scans and 3 A-scans), or the centre window's vertex height without it.
    const double centre_sample = std::isnan(centre_sample_mm) ? cft_sample_mm : centre_sample_mm;
    for (const auto& h0 : lines) {
        CubeHalfLine& h = out.free_fits.emplace_back(h0);
        fit_half_line(h, centre_sample, params, free_fs);
        if (!h.valid) continue;
        sum += h.interior.control[0].y();
        ++count;
    }
    if (count > 0) out.cft_mm = sum / count;
    return out;
}

void final_fit(RadialSamples& s, const CftPass& cft, const CubeParams& params, double crest_mm) {
    // Under noise the final fit uses the sector bins (docs/algorithms/cube.md "Radial samples
    // under noise"), started from the CFT pass's curves.
    if (s.noise_adaptive) sector_bin_samples(s.sector_nodes, s.half_lines, &cft.free_fits, s.noise_sd_mm);
    const FitSettings fs{.max_rounds = params.max_rounds,
                         .energy_tolerance = params.energy_tolerance,
                         .free_start_height = false,
                         .rim_point = params.rim_point,
                         .crest_tolerance_mm = crest_mm,
                         .covariance = s.noise_adaptive};
    for (std::size_t i = 0; i < s.half_lines.size(); ++i) {
        CubeHalfLine& h = s.half_lines[i];
        h.h_mm[0] = cft.cft_mm;
        const BilinearSamples regular{s.radii, s.bilinear.empty() ? h.h_mm : s.bilinear[i]};
        fit_half_line(h, cft.cft_mm, params, fs, &cft.free_fits[i],
                      s.bilinear.empty() ? nullptr : &regular);
    }
}

void check_macula_field(const ThicknessMap& m, const CubeParams& params, bool line_scan) {
    const double width = (m.cols - 1) * m.dx_mm;
    const double height = (m.rows - 1) * m.dy_mm;
    if (width >= params.radius_mm && (line_scan || height >= params.radius_mm)) return;
    std::ostringstream s;
    s.precision(4);
    s << "the scan's field (" << width << " x " << height
      << " mm) is smaller than the model's half-lines of " << params.radius_mm
      << " mm: no half-line can reach the rim (a smaller --radius-mm, or a larger scan)";
    throw AnalysisError(s.str());
}

}  // namespace cube_detail

std::string_view to_string(RimPoint r) { return r == RimPoint::kCrest ? "crest" : "maximum"; }

RimPoint parse_rim_point(std::string_view s) {
    if (s == "crest") return RimPoint::kCrest;
    if (s == "maximum") return RimPoint::kMaximum;
    throw UsageError("rim point '" + std::string(s) + "': expected crest or maximum");
}

void CubeParams::validate() const {
    auto bad = [](const std::string& field, const std::string& why) {
        throw UsageError("macula parameter " + field + ": " + why);
    };
    lateral_registration.validate();
    if (num_half_lines < 4 || num_half_lines % 2 != 0 || num_half_lines > 3600) {
        bad("num_half_lines", "must be even and in 4..3600");
    }
    if (!(radius_mm > 0.0) || radius_mm > 10.0) bad("radius_mm", "must be in (0, 10] mm");
    // 0.1 um: 20x finer than any Spectralis A-scan spacing, and at most 1e5 samples per
    // half-line (R <= 10 mm) before anything is allocated.
    if (!(sample_spacing_mm >= 0.0) || sample_spacing_mm > radius_mm / 8.0 ||
        (sample_spacing_mm > 0.0 && sample_spacing_mm < 1e-4)) {
        bad("sample_spacing_mm", "must be 0 (ScaleX) or in [0.0001 mm, radius/8]");
    }
    if (!(tau_mm > 0.0) || tau_mm > 0.2) bad("tau_mm", "must be in (0, 0.2] mm");
    if (!(inner_radius_mm > 0.0) || inner_radius_mm >= radius_mm) {
        bad("inner_radius_mm", "must be in (0, radius)");
    }
    if (!(search_radius_mm >= 0.0) || search_radius_mm > 5.0) {
        bad("search_radius_mm", "must be in [0, 5] mm");
    }
    if (!(tie_tolerance_mm >= 0.0) || tie_tolerance_mm > 0.01) {
        bad("tie_tolerance_mm", "must be in [0, 0.01] mm");
    }
    if (!(centre_smoothing_mm >= 0.0) || centre_smoothing_mm > 0.5) {
        bad("centre_smoothing_mm", "must be in [0, 0.5] mm");
    }
    if (!(centre_fit_radius_mm >= 0.0) || centre_fit_radius_mm > 0.5) {
        bad("centre_fit_radius_mm", "must be in [0, 0.5] mm");
    }
    if (max_rounds < 1 || max_rounds > 100000) bad("max_rounds", "must be in 1..100000");
    if (!(energy_tolerance > 0.0) || energy_tolerance >= 1.0) {
        bad("energy_tolerance", "must be in (0, 1)");
    }
    if (!(rmse_warning_um > 0.0)) bad("rmse_warning_um", "must be > 0");
    if (!(local_fit_min_noise_um >= 0.0)) {
        bad("local_fit_min_noise_um", "must be >= 0 (+inf: always bilinear)");
    }
    if (centre_mm && !centre_mm->allFinite()) bad("centre_mm", "must be finite");
}

CubeResult analyse_macula(const io::Scan& scan, const CubeParams& params) {
    params.validate();
    if (is_radial_scan(scan)) return analyse_macula_radial(scan, params);
    CubeResult res;
    res.line_scan = check_macula_scan(scan);
    res.map = thickness_map(scan);
    check_macula_field(res.map, params, res.line_scan);
    const double noise_sd_mm = thickness_noise_sd(res.map);
    res.thickness_noise_sd_um = noise_sd_mm * 1e3;
    // 3 SDs: a sample that low below the maximum one is its rival only if the two noises differ
    // by > 3 / sqrt(2) = 2.1 SDs, which happens to ~2 % of pairs.
    const double crest_mm = 3.0 * noise_sd_mm;
    // Segmentation noise worth a noise-adaptive estimator (centre window, radial samples).
    const bool noisy = !res.line_scan && res.thickness_noise_sd_um >= params.local_fit_min_noise_um;
    const ScanGeometry geo(scan);

    Centre centre = find_centre({.scan = scan,
                                 .map = res.map,
                                 .geo = geo,
                                 .params = params,
                                 .line_scan = res.line_scan,
                                 .noisy = noisy,
                                 .noise_sd_mm = noise_sd_mm});
    const double centre_sample_mm = centre.sample_mm;
    const PitFloor floor = centre.floor;
    take_centre(res, std::move(centre));

    RadialSamples samples = radial_samples(res.map, geo, params, res.centre_mm, res.cft_mm,
                                           scan.meta.scale_x_mm, res.line_scan, noisy, floor);
    res.sample_spacing_mm = samples.spacing_mm;
    res.noise_adaptive_samples = samples.noise_adaptive;
    samples.noise_sd_mm = noise_sd_mm;
    fit_half_lines(res, samples, centre_sample_mm, params, crest_mm);

    summarise_macula(res, params);
    macula_qc(res, scan, geo, params);
    check_macula_result(res, scan);
    return res;
}

}  // namespace octshape::retina
