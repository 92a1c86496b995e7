#include "octshape/retina/phantom_common.h"
#include "octshape/retina/phantom_speckle.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include <Eigen/LU>

#include "octshape/error.h"

namespace octshape::retina::phantom {
namespace {

std::uint64_t splitmix64(std::uint64_t& x) {
    x += 0x9E3779B97F4A7C15ULL;
    std::uint64_t z = x;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

// 2024-03-14 09:30:00 UTC as a Windows FILETIME, and the same day as an OLE date.
constexpr std::uint64_t kExamFiletime = 133548822000000000ULL;
constexpr double kVisitOle = 45365.0;
constexpr double kBirthOle = 25569.0;  // 1970-01-01

void require(bool ok, const std::string& field, const std::string& why) {
    if (!ok) throw UsageError("phantom layout: " + field + " " + why);
}

}  // namespace

Rng::Rng(std::uint64_t seed, std::uint64_t stream) {
    std::uint64_t x = seed;
    const std::uint64_t mix = splitmix64(x) ^ (stream * 0xD1B54A32D192ED03ULL);
    x = mix;
    for (auto& s : s_) s = splitmix64(x);
}

std::uint64_t Rng::next() {
    const std::uint64_t result = rotl(s_[1] * 5, 7) * 9;
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
}

double Rng::uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }

double Rng::normal() {
    if (has_spare_) {
        has_spare_ = false;
        return spare_;
    }
    double u = 0.0;
    double v = 0.0;
    double s = 0.0;
    do {
        u = 2.0 * uniform() - 1.0;
        v = 2.0 * uniform() - 1.0;
        s = u * u + v * v;
    } while (s >= 1.0 || s == 0.0);
    const double m = std::sqrt(-2.0 * std::log(s) / s);
    spare_ = v * m;
    has_spare_ = true;
    return u * m;
}

double Rng::gamma(double shape) {
    if (shape < 1.0) {
        // Gamma(a) = Gamma(a + 1) * U^(1/a).
        const double g = gamma(shape + 1.0);
        return g * std::pow(uniform() + 0x1.0p-54, 1.0 / shape);
    }
    const double d = shape - 1.0 / 3.0;
    const double c = 1.0 / std::sqrt(9.0 * d);
    for (;;) {
        const double x = normal();
        double v = 1.0 + c * x;
        if (v <= 0.0) continue;
        v = v * v * v;
        const double u = uniform();
        if (u < 1.0 - 0.0331 * x * x * x * x) return d * v;
        if (std::log(u) < 0.5 * x * x + d * (1.0 - v + std::log(v))) return d * v;
    }
}

void VolumeLayout::validate() const {
    require(pattern == io::ScanPattern::kVolume || pattern == io::ScanPattern::kLine ||
                pattern == io::ScanPattern::kRadial,
            "pattern", "must be volume, line or radial");
    require(!vertical || pattern != io::ScanPattern::kRadial, "vertical",
            "applies to volumes and lines only");
    require(laterality == io::Laterality::kOD || laterality == io::Laterality::kOS, "laterality",
            "must be OD or OS");
    require(size_x >= 2 && size_x <= 4096, "size_x", "must be in 2..4096");
    require(size_z >= 16 && size_z <= 4096, "size_z", "must be in 16..4096");
    if (pattern == io::ScanPattern::kLine) {
        require(num_bscans == 1, "num_bscans", "must be 1 for a line scan");
    } else {
        require(num_bscans >= 2 && num_bscans <= 1024, "num_bscans", "must be in 2..1024");
        require(std::isfinite(distance_mm) && distance_mm > 0.0, "distance_mm", "must be > 0");
    }
    require(std::isfinite(scale_x_mm) && scale_x_mm > 0.0, "scale_x_mm", "must be > 0");
    require(std::isfinite(scale_z_mm) && scale_z_mm > 0.0, "scale_z_mm", "must be > 0");
    require(num_seg >= 2 && num_seg <= io::kNumKnownLayers, "num_seg", "must be in 2..17");
    require(slo_size_px >= 16 && slo_size_px <= 4096, "slo_size_px", "must be in 16..4096");
    require(std::isfinite(slo_margin) && slo_margin >= 1.0, "slo_margin", "must be >= 1");
}

double GridFrame::anatomical_angle_deg(double dx, double dy) const {
    const Eigen::Vector2d a = grid_to_anatomical * Eigen::Vector2d(dx, dy);
    double deg = std::atan2(a.y(), a.x()) * 180.0 / std::numbers::pi;
    if (deg < 0.0) deg += 360.0;
    if (deg >= 360.0) deg -= 360.0;
    return deg;
}

Eigen::Vector2d GridFrame::grid_direction(double anatomical_deg) const {
    const double t = anatomical_deg * std::numbers::pi / 180.0;
    // grid_to_anatomical is a signed permutation here, so its inverse is its transpose; use the
    // general inverse anyway so that the relation holds for any placement.
    const Eigen::Vector2d g =
        grid_to_anatomical.inverse() * Eigen::Vector2d(std::cos(t), std::sin(t));
    return g.normalized();
}

GridFrame grid_frame(const VolumeLayout& layout) {
    layout.validate();
    GridFrame f;
    f.width_mm = (layout.size_x - 1) * layout.scale_x_mm;
    f.height_mm = layout.num_bscans > 1 ? (layout.num_bscans - 1) * layout.distance_mm : 0.0;
    const double side = layout.slo_margin * std::max(f.width_mm, f.height_mm);
    f.slo_scale_mm = side / layout.slo_size_px;
    // A-scans left to right: grid +x = SLO +x. First B-scan most inferior (largest SLO y):
    // grid +y = SLO -y. The grid is centred on the SLO image.
    f.grid_to_slo << 1.0, 0.0, 0.0, -1.0;
    f.origin_slo_mm = {side / 2 - f.width_mm / 2, side / 2 + f.height_mm / 2};
    if (layout.vertical) {
        // A-scans top to bottom (grid +x = SLO +y), the first B-scan leftmost (grid +y = SLO +x).
        f.grid_to_slo << 0.0, 1.0, 1.0, 0.0;
        f.origin_slo_mm = {side / 2 - f.height_mm / 2, side / 2 - f.width_mm / 2};
    }
    // On the SLO (a fundus view), superior is up (-y) and nasal is towards the optic disc:
    // right (+x) for OD, left (-x) for OS.
    const double nasal = layout.laterality == io::Laterality::kOS ? -1.0 : 1.0;
    Eigen::Matrix2d slo_to_anat;
    slo_to_anat << nasal, 0.0, 0.0, -1.0;
    f.grid_to_anatomical = slo_to_anat * f.grid_to_slo;
    return f;
}

io::Scan make_scan_frame(const VolumeLayout& layout) {
    const GridFrame f = grid_frame(layout);
    io::Scan s;
    s.source_path = "phantom";
    io::ScanMeta& m = s.meta;
    m.format = io::SourceFormat::kVol;
    m.version = "HSF-OCT-103";
    m.size_x = layout.size_x;
    m.size_z = layout.size_z;
    m.scale_x_mm = layout.scale_x_mm;
    m.scale_z_mm = layout.scale_z_mm;
    m.distance_mm = layout.num_bscans > 1 ? layout.distance_mm : 0.0;
    m.size_x_slo = layout.slo_size_px;
    m.size_y_slo = layout.slo_size_px;
    m.scale_x_slo_mm = f.slo_scale_mm;
    m.scale_y_slo_mm = f.slo_scale_mm;
    m.field_size_slo_deg = layout.slo_field_deg;
    m.scan_focus_dpt = 0.0;
    m.laterality = layout.laterality;
    m.scan_position_raw = layout.laterality == io::Laterality::kOS ? "OS" : "OD";
    m.pattern = layout.pattern;
    m.scan_pattern_code = static_cast<std::int32_t>(layout.pattern);
    m.exam_time_filetime = kExamFiletime;
    m.visit_date_ole = kVisitOle;
    m.ids.id = "PHANTOM";
    m.ids.reference_id = "PHANTOM-REF";
    m.ids.pid = 0;
    m.ids.patient_id = "FAKE-PHANTOM-0000";
    m.ids.dob_ole = kBirthOle;
    m.ids.vid = 0;
    m.ids.visit_id = "FAKE-VISIT-0000";
    m.prog_id = "octshape phantom";
    // Segmentation lines live inside the B-scan header after OffSeg = 256; round the header up
    // to whole KiB as the device does.
    const std::uint64_t need = 256 + static_cast<std::uint64_t>(layout.num_seg) *
                                         static_cast<std::uint64_t>(layout.size_x) * 4;
    m.bscan_hdr_size = static_cast<std::uint32_t>((need + 1023) / 1024 * 1024);

    s.bscans.resize(static_cast<std::size_t>(layout.num_bscans));
    const auto nan = std::numeric_limits<float>::quiet_NaN();
    for (int b = 0; b < layout.num_bscans; ++b) {
        io::BScan& bs = s.bscans[static_cast<std::size_t>(b)];
        const double y = layout.num_bscans > 1 ? b * layout.distance_mm : 0.0;
        const Eigen::Vector2d start = f.to_slo({0.0, y});
        const Eigen::Vector2d end = f.to_slo({f.width_mm, y});
        bs.start_x_mm = start.x();
        bs.start_y_mm = start.y();
        bs.end_x_mm = end.x();
        bs.end_y_mm = end.y();
        bs.off_seg = 256;
        bs.quality = 30.0F;
        bs.seg.assign(static_cast<std::size_t>(layout.num_seg),
                      std::vector<float>(static_cast<std::size_t>(layout.size_x), nan));
    }
    return s;
}

ColumnBoundaries retina_boundaries(double ilm_px,
                                   double bm_px,
                                   double scale_z_mm,
                                   const RetinaLayers& layers) {
    const double t = std::max(0.0, (bm_px - ilm_px) * scale_z_mm);
    const double outer = std::min(layers.outer_mm, t);
    const double inner = t - outer;
    const double pr = std::min(layers.photoreceptor_mm, 0.45 * outer);
    // Depths below the ILM in mm.
    std::array<double, 11> mm{};
    double acc = 0.0;
    mm[0] = 0.0;
    for (int k = 0; k < 5; ++k) {
        acc += layers.inner_fractions[static_cast<std::size_t>(k)] * inner;
        mm[static_cast<std::size_t>(k + 1)] = acc;
    }
    mm[5] = inner;  // OPL/ONL exactly, whatever rounding the fractions had
    mm[6] = t - pr;                // ELM
    mm[7] = t - pr + 0.30 * pr;    // inner segments -> EZ
    mm[8] = t - pr + 0.45 * pr;    // EZ -> outer segments
    mm[9] = t - 0.30 * pr;         // RPE top
    mm[10] = t;                    // BM
    ColumnBoundaries b;
    for (std::size_t k = 0; k < mm.size(); ++k) b.depth_px[k] = ilm_px + mm[k] / scale_z_mm;
    b.depth_px[10] = bm_px;
    return b;
}

void layered_retina_column(const ColumnBoundaries& b,
                           double scale_z_mm,
                           const RetinaLayers& layers,
                           std::span<float> column) {
    // Values of the 12 depth intervals: above ILM, the 10 layers, below BM (choroid).
    const std::array<double, 11> v{layers.vitreous, layers.rnfl, layers.gcl, layers.ipl,
                                   layers.inl, layers.opl, layers.onl, layers.inner_segments,
                                   layers.ez, layers.outer_segments, layers.rpe};
    const double bm = b.depth_px[10];
    const double k = scale_z_mm / layers.choroid_decay_mm;  // decay per pixel
    // Integral of the profile from -inf-like reference `lo` to `hi`, both >= some start;
    // computed piecewise: constant pieces above BM, exponential below.
    auto integral = [&](double lo, double hi) {
        double sum = 0.0;
        // Constant pieces: interval i spans [b[i-1], b[i]) with b[-1] = -inf, value v[i].
        for (std::size_t i = 0; i < v.size(); ++i) {
            const double a = i == 0 ? -std::numeric_limits<double>::infinity()
                                    : b.depth_px[i - 1];
            const double c = b.depth_px[i];
            const double l = std::max(lo, a);
            const double h = std::min(hi, c);
            if (h > l) sum += v[i] * (h - l);
        }
        // Choroid below BM: choroid * exp(-k (d - bm)).
        const double l = std::max(lo, bm);
        if (hi > l) {
            sum += layers.choroid / k * (std::exp(-k * (l - bm)) - std::exp(-k * (hi - bm)));
        }
        return sum;
    };
    for (std::size_t p = 0; p < column.size(); ++p) {
        const double c = static_cast<double>(p);
        column[p] = static_cast<float>(integral(c - 0.5, c + 0.5));
    }
}

namespace {

// Normalised 1-D Gaussian kernel (sum of squares 1) for a field whose intensity correlation has
// half-width `half_width_px`; {1} for 0.
std::vector<double> speckle_kernel(double half_width_px) {
    if (!(half_width_px > 0.0)) return {1.0};
    const double sd = half_width_px / std::sqrt(2.0 * std::numbers::ln2);
    const int r = static_cast<int>(std::ceil(3.0 * sd));
    std::vector<double> k(static_cast<std::size_t>(2 * r + 1));
    double sum2 = 0.0;
    for (int i = -r; i <= r; ++i) {
        const double v = std::exp(-0.5 * i * i / (sd * sd));
        k[static_cast<std::size_t>(i + r)] = v;
        sum2 += v * v;
    }
    for (double& v : k) v /= std::sqrt(sum2);
    return k;
}

// Correlated speckle (SpeckleParams): mean-1 multipliers, size_z x size_x row-major.
std::vector<double> correlated_speckle(int size_x,
                                       int size_z,
                                       const SpeckleParams& sp,
                                       Rng& rng) {
    const std::vector<double> kz = speckle_kernel(sp.axial_half_width_px);
    const std::vector<double> kx = speckle_kernel(sp.lateral_half_width_px);
    const int rz = static_cast<int>(kz.size() / 2);
    const int rx = static_cast<int>(kx.size() / 2);
    const int wz = size_z + 2 * rz, wx = size_x + 2 * rx;  // the white field with its margins
    const int looks = static_cast<int>(std::lround(sp.looks));
    std::vector<double> out(static_cast<std::size_t>(size_x) * size_z, 0.0);
    std::vector<double> white(static_cast<std::size_t>(wz) * wx);
    std::vector<double> rows(static_cast<std::size_t>(size_z) * wx);  // smoothed along depth
    for (int l = 0; l < looks; ++l) {
        for (int part = 0; part < 2; ++part) {  // real and imaginary parts
            for (double& v : white) v = rng.normal();
            std::fill(rows.begin(), rows.end(), 0.0);
            for (int z = 0; z < size_z; ++z) {
                for (int j = 0; j <= 2 * rz; ++j) {
                    const double* src = &white[static_cast<std::size_t>(z + j) * wx];
                    double* dst = &rows[static_cast<std::size_t>(z) * wx];
                    for (int x = 0; x < wx; ++x) dst[x] += kz[j] * src[x];
                }
            }
            for (int z = 0; z < size_z; ++z) {
                const double* src = &rows[static_cast<std::size_t>(z) * wx];
                for (int x = 0; x < size_x; ++x) {
                    double f = 0.0;
                    for (int j = 0; j <= 2 * rx; ++j) f += kx[j] * src[x + j];
                    // |F|^2 / 2 over both parts: exponential of mean 1 per look.
                    out[static_cast<std::size_t>(z) * size_x + x] += 0.5 * f * f / looks;
                }
            }
        }
    }
    return out;
}

}  // namespace

void render_bscan(io::BScan& bscan,
                  int size_x,
                  int size_z,
                  const ColumnFunction& reflectance,
                  const SpeckleParams& speckle,
                  std::uint64_t seed,
                  std::uint64_t stream) {
    if (!(speckle.looks > 0.0)) throw UsageError("speckle: looks must be > 0");
    const bool grain = speckle.axial_half_width_px > 0.0 || speckle.lateral_half_width_px > 0.0;
    if (!(speckle.axial_half_width_px >= 0.0 && speckle.axial_half_width_px <= 20.0 &&
          speckle.lateral_half_width_px >= 0.0 && speckle.lateral_half_width_px <= 20.0)) {
        throw UsageError("speckle: the grain half-widths must be in 0..20 px");
    }
    if (grain && (speckle.looks > 64.0 || std::abs(speckle.looks - std::round(speckle.looks)) >
                                              1e-9)) {
        throw UsageError("speckle: with a grain, looks must be a whole number in 1..64");
    }
    const auto nx = static_cast<std::size_t>(size_x);
    const auto nz = static_cast<std::size_t>(size_z);
    bscan.pixels.assign(nx * nz, 0.0F);
    std::vector<float> column(nz);
    Rng rng(seed, stream);
    const std::vector<double> field =
        grain ? correlated_speckle(size_x, size_z, speckle, rng) : std::vector<double>{};
    const double inv_looks = 1.0 / speckle.looks;
    for (std::size_t a = 0; a < nx; ++a) {
        std::fill(column.begin(), column.end(), 0.0F);
        reflectance(static_cast<int>(a), column);
        for (std::size_t z = 0; z < nz; ++z) {
            // (without a grain: the same expression, so the same bits, as before grains)
            const double value = grain ? column[z] * field[z * nx + a]
                                       : column[z] * rng.gamma(speckle.looks) * inv_looks;
            bscan.pixels[z * nx + a] = static_cast<float>(std::clamp(value, 0.0, 1.0));
        }
    }
}

void render_slo(io::Scan& scan,
                const std::function<double(double x_slo_mm, double y_slo_mm)>& brightness,
                std::uint64_t seed) {
    const auto nx = static_cast<std::size_t>(scan.meta.size_x_slo);
    const auto ny = static_cast<std::size_t>(scan.meta.size_y_slo);
    scan.slo.assign(nx * ny, 0);
    Rng rng(seed, 0x510ULL);
    for (std::size_t j = 0; j < ny; ++j) {
        for (std::size_t i = 0; i < nx; ++i) {
            const double x = (static_cast<double>(i) + 0.5) * scan.meta.scale_x_slo_mm;
            const double y = (static_cast<double>(j) + 0.5) * scan.meta.scale_y_slo_mm;
            const double value = brightness(x, y) * (1.0 + 0.05 * rng.normal());
            scan.slo[j * nx + i] =
                static_cast<std::uint8_t>(std::lround(std::clamp(value, 0.0, 1.0) * 255.0));
        }
    }
}

}  // namespace octshape::retina::phantom

namespace octshape::retina::phantom {
namespace {

// Linear interpolation of the lag where an autocorrelation falls to 0.5 (NaN: not within 3).
double half_width(const std::array<double, 4>& acf) {
    for (std::size_t j = 1; j < acf.size(); ++j) {
        if (acf[j] < 0.5) {
            return static_cast<double>(j - 1) + (acf[j - 1] - 0.5) / (acf[j - 1] - acf[j]);
        }
    }
    return std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

SpeckleStats speckle_statistics(const io::BScan& bscan,
                                int size_x,
                                int size_z,
                                std::span<const int> top_row,
                                int rows,
                                int box_half) {
    if (size_x < 1 || size_z < 1 || rows < 1 || box_half < 1 ||
        top_row.size() != static_cast<std::size_t>(size_x) ||
        bscan.pixels.size() !=
            static_cast<std::size_t>(size_x) * static_cast<std::size_t>(size_z)) {
        throw UsageError("speckle statistics: bad band or image size");
    }
    const int h = box_half;
    const int nk = rows + 2 * h;  // band rows with the box margin above and below
    // The band in its own coordinates, NaN where a pixel is outside the image or the band.
    std::vector<double> band(static_cast<std::size_t>(size_x) * nk,
                             std::numeric_limits<double>::quiet_NaN());
    auto at = [&](int a, int k) -> double& { return band[static_cast<std::size_t>(a) * nk + k]; };
    for (int a = 0; a < size_x; ++a) {
        if (top_row[a] < 0) continue;
        for (int k = 0; k < nk; ++k) {
            const int z = top_row[a] - h + k;
            if (z >= 0 && z < size_z) {
                at(a, k) = bscan.pixels[static_cast<std::size_t>(z) * size_x + a];
            }
        }
    }
    // Normalised values (NaN = unused) and their raw values.
    std::vector<double> norm(band.size(), std::numeric_limits<double>::quiet_NaN());
    double sum = 0.0, sum2 = 0.0, raw = 0.0, zeros = 0.0;
    std::size_t n = 0;
    for (int a = h; a + h < size_x; ++a) {
        for (int k = h; k < h + rows; ++k) {
            double box = 0.0;
            bool whole = true;
            for (int i = -h; i <= h && whole; ++i) {
                for (int j = -h; j <= h; ++j) {
                    const double v = at(a + i, k + j);
                    if (std::isnan(v)) {
                        whole = false;
                        break;
                    }
                    box += v;
                }
            }
            if (!whole || !(box > 0.0)) continue;
            const double v = at(a, k) / (box / ((2 * h + 1) * (2 * h + 1)));
            norm[static_cast<std::size_t>(a) * nk + k] = v;
            sum += v;
            sum2 += v * v;
            raw += at(a, k);
            zeros += at(a, k) == 0.0 ? 1.0 : 0.0;
            ++n;
        }
    }
    if (n < 2) throw AnalysisError("speckle statistics: no usable pixel in the band");
    SpeckleStats s;
    s.count = n;
    const double mean = sum / static_cast<double>(n);
    const double var = sum2 / static_cast<double>(n) - mean * mean;
    s.mean_raw = raw / static_cast<double>(n);
    s.zero_fraction = zeros / static_cast<double>(n);
    s.contrast = std::sqrt(var) / mean;
    s.shape = mean * mean / var;
    auto acf = [&](int da, int dk) {
        double c = 0.0;
        std::size_t m = 0;
        for (int a = 0; a + da < size_x; ++a) {
            for (int k = 0; k + dk < nk; ++k) {
                const double u = norm[static_cast<std::size_t>(a) * nk + k];
                const double w = norm[static_cast<std::size_t>(a + da) * nk + k + dk];
                if (std::isnan(u) || std::isnan(w)) continue;
                c += (u - mean) * (w - mean);
                ++m;
            }
        }
        return m > 0 ? c / static_cast<double>(m) / var : std::numeric_limits<double>::quiet_NaN();
    };
    for (int j = 0; j < 4; ++j) {
        s.acf_axial[j] = acf(0, j);
        s.acf_lateral[j] = acf(j, 0);
    }
    s.half_width_axial_px = half_width(s.acf_axial);
    s.half_width_lateral_px = half_width(s.acf_lateral);
    return s;
}

}  // namespace octshape::retina::phantom
