// Accuracy table of the CuBe analysis on the macula phantoms (docs/algorithms/cube.md,
// "Accuracy"): every parameter's error against the generator's truth, for the Bezier family
// (exactly representable) and the Scheibe family (model mismatch) at 61/97/193 B-scans, and the
// Bezier family at 193 B-scans with 1 axial pixel of segmentation noise (several seeds).
// Usage: macula_accuracy [NOISE_SEEDS]   (default 5)

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "octshape/retina/cube.h"
#include "octshape/retina/phantom_macula.h"
#include "octshape/retina/stats.h"

namespace {

using namespace octshape::retina;

struct Row {
    const char* name;
    double error;   // absolute, in the unit below
    double rel;     // relative to the true value (%)
    const char* unit;
    double signed_rel = 0.0;  // (estimate / truth - 1) in %
};

std::vector<Row> errors(const CubeResult& r, const MaculaTruth& t) {
    auto rel = [](double v, double truth) { return 100.0 * std::fabs(v / truth - 1.0); };
    auto row = [&](const char* name, double v, double truth, double scale, const char* unit) {
        return Row{name, std::fabs(v - truth) * scale, rel(v, truth), unit,
                   100.0 * (v / truth - 1.0)};
    };
    std::vector<Row> rows{
        row("cft", r.cft_mm, t.cft_mm, 1e3, "um"),
        row("rim_height", r.rim_height_mm, t.rim_height_mm, 1e3, "um"),
        row("pit_depth", r.pit_depth_mm, t.pit_depth_mm, 1e3, "um"),
        row("rim_diameter", r.rim.diameter_mm, t.rim.diameter_mm, 1e3, "um"),
        row("rim_area", r.rim.area_mm2, t.rim.area_mm2, 1.0, "mm2"),
        row("rim_lambda_major", r.rim.eigenvalues_mm2[0], t.rim.eigenvalues_mm2[0], 1.0, "mm2"),
        row("rim_lambda_minor", r.rim.eigenvalues_mm2[1], t.rim.eigenvalues_mm2[1], 1.0, "mm2"),
        row("max_slope", r.max_pit_slope_deg, t.max_pit_slope_deg, 1.0, "deg"),
        row("slope_diameter", r.slope.diameter_mm, t.slope.diameter_mm, 1e3, "um"),
        row("slope_area", r.slope.area_mm2, t.slope.area_mm2, 1.0, "mm2"),
        row("flat_diameter", r.pit_flat_diameter_mm, t.pit_flat_diameter_mm, 1e3, "um"),
        row("flat_area", r.pit_flat.area_mm2, t.pit_flat.area_mm2, 1.0, "mm2"),
        row("rim_volume", r.rim_volume_mm3, t.rim_volume_mm3, 1.0, "mm3"),
        row("inner_rim_volume", r.inner_rim_volume_mm3, t.inner_rim_volume_mm3, 1.0, "mm3"),
        row("pit_volume", r.pit_volume_mm3, t.pit_volume_mm3, 1.0, "mm3"),
    };
    if (t.alpha_mean_mm) rows.push_back(row("alpha_mean", r.alpha_mean_mm, *t.alpha_mean_mm, 1e3, "um"));
    if (t.beta_mean_mm) rows.push_back(row("beta_mean", r.beta_mean_mm, *t.beta_mean_mm, 1e3, "um"));
    rows.push_back(Row{"rmse", r.rmse_um, 0.0, "um"});
    return rows;
}

// Every half-line's rim radius error over the noisy seeds, and how it depends on whether the
// fitted exterior rests on a bound of its graph constraints (docs/algorithms/cube.md, "Bias
// under noise"): alpha_ext = 0, P2.x = P1.x, P2.x = P3.x (= R), or none.
class RimErrors {
  public:
    void add(const CubeResult& r, const MaculaTruth& t) {
        for (std::size_t i = 0; i < r.half_lines.size() && i < t.half_lines.size(); ++i) {
            const CubeHalfLine& h = r.half_lines[i];
            if (!h.valid) continue;
            const double e = 1e3 * (h.rim_radius_mm - t.half_lines[i].rim_radius_mm);
            const auto& c = h.exterior.control;
            constexpr double kAt = 1e-9;  // mm: on the bound
            const int group = c[1].x() - c[0].x() < kAt   ? 1
                              : c[2].x() - c[1].x() < kAt ? 2
                              : c[3].x() - c[2].x() < kAt ? 3
                                                          : 0;
            errors_.push_back(e);
            sum_[group] += e;
            ++count_[group];
        }
    }
    void print() const {
        if (errors_.size() < 2) return;
        const Summary st = summarise(errors_);
        std::vector<double> e = errors_;
        const auto mid = e.begin() + static_cast<std::ptrdiff_t>(e.size() / 2);
        std::nth_element(e.begin(), mid, e.end());
        double m3 = 0.0;  // third central moment, for the skewness
        for (const double x : errors_) m3 += std::pow(x - st.mean, 3) / static_cast<double>(st.n);
        std::printf("\nrim radius per half-line (um), %zu half-lines: mean %+.2f, median %+.2f, SD "
                    "%.2f, skewness %.2f\n",
                    st.n, st.mean, *mid, st.sd, m3 / std::pow(st.sd, 3));
        static const char* const names[4] = {"exterior free", "alpha_ext = 0", "P2.x = P1.x",
                                             "P2.x = R"};
        for (int g = 0; g < 4; ++g) {
            std::printf("  %-14s %4d half-lines, mean rim radius error %+.2f um\n", names[g],
                        count_[g], count_[g] > 0 ? sum_[g] / count_[g] : 0.0);
        }
    }

  private:
    std::vector<double> errors_;
    std::array<double, 4> sum_{};
    std::array<int, 4> count_{};
};

MaculaPhantomParams volume(MaculaFamily f, int bscans) {
    MaculaPhantomParams p;
    p.family = f;
    p.num_bscans = bscans;
    p.pixels = false;
    p.fovea_dx_mm = 0.0237;  // off every grid node, as in tests/retina/cube_test.cpp
    p.fovea_dy_mm = -0.0311;
    return p;
}

void print_block(const std::string& title, const std::vector<std::vector<Row>>& cols,
                 const std::vector<std::string>& heads) {
    std::printf("\n%s\n%-18s %-4s", title.c_str(), "parameter", "unit");
    for (const auto& h : heads) std::printf(" %14s %8s", h.c_str(), "%");
    std::printf("\n");
    for (std::size_t i = 0; i < cols.front().size(); ++i) {
        std::printf("%-18s %-4s", cols.front()[i].name, cols.front()[i].unit);
        for (const auto& c : cols) std::printf(" %14.6g %8.3f", c[i].error, c[i].rel);
        std::printf("\n");
    }
}

}  // namespace

int main(int argc, char** argv) {
    const int seeds = argc > 1 ? std::max(1, std::atoi(argv[1])) : 5;
    for (const MaculaFamily f : {MaculaFamily::kBezier, MaculaFamily::kScheibe}) {
        std::vector<std::vector<Row>> cols;
        std::vector<std::string> heads;
        for (const int nb : {61, 97, 193}) {
            const MaculaPhantom ph = make_macula_phantom(volume(f, nb));
            cols.push_back(errors(analyse_macula(ph.scan), ph.truth));
            heads.push_back(std::to_string(nb));
        }
        print_block(to_string(f) + ": |error| (abs, %) at 61 / 97 / 193 B-scans", cols, heads);
    }
    // 1 axial pixel of thickness noise: sigma / sqrt(2) on ILM and on BM (as in the unit test).
    std::vector<std::vector<Row>> cols;
    std::vector<std::string> heads;
    std::vector<Row> mean;
    std::vector<double> sum;     // of the signed relative errors
    std::vector<double> sum_sq;  // of the relative errors squared
    RimErrors rims;
    for (int s = 0; s < seeds; ++s) {
        MaculaPhantomParams p = volume(MaculaFamily::kBezier, 193);
        p.noise_um = 3.8717 / std::sqrt(2.0);
        p.seed = static_cast<std::uint64_t>(7 + s);
        const MaculaPhantom ph = make_macula_phantom(p);
        const CubeResult r = analyse_macula(ph.scan);
        const auto e = errors(r, ph.truth);
        rims.add(r, ph.truth);
        if (mean.empty()) {
            mean = e;
            for (auto& m : mean) m.error = m.rel = 0.0;
            sum.assign(e.size(), 0.0);
            sum_sq.assign(e.size(), 0.0);
        }
        for (std::size_t i = 0; i < e.size(); ++i) {
            sum[i] += e[i].signed_rel;
            sum_sq[i] += e[i].rel * e[i].rel;
            mean[i].error = std::max(mean[i].error, e[i].error);
            mean[i].rel = std::max(mean[i].rel, e[i].rel);
        }
        if (s < 3) {
            cols.push_back(e);
            heads.push_back("seed " + std::to_string(p.seed));
        }
    }
    cols.push_back(mean);
    heads.push_back("max of " + std::to_string(seeds));
    print_block("Bezier, 193 B-scans, noise sigma 3.87 um: |error|", cols, heads);
    // Over the seeds: the mean signed relative error (the bias) and the RMS relative error.
    std::printf("\n%-18s %12s %12s %12s\n", "parameter", "mean (%)", "RMS (%)", "max (%)");
    for (std::size_t i = 0; i < mean.size(); ++i) {
        if (mean[i].name == std::string("rmse")) continue;
        std::printf("%-18s %12.3f %12.3f %12.3f\n", mean[i].name, sum[i] / seeds,
                    std::sqrt(sum_sq[i] / seeds), mean[i].rel);
    }
    rims.print();
    return 0;
}
