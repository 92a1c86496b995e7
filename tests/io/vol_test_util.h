#pragma once
// Helpers shared by the .vol tests: a synthetic scan with every field set, comparison of two
// scans field by field, and little-endian byte patching of a file held in memory.

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

#include "octshape/io/scan.h"
#include "octshape/io/vol.h"

namespace octshape::test {

struct SyntheticVolParams {
    int num_bscans = 3;
    int size_x = 16;
    int size_z = 12;
    int num_lines = 17;
    int slo_x = 10;
    int slo_y = 8;
    bool pixels = true;
};

// A scan with every field the writer stores set to a non-default value. Segmentation holds
// sub-pixel depths and some missing values; pixels and SLO hold distinct values.
inline io::Scan make_synthetic_scan(const SyntheticVolParams& p = {}) {
    io::Scan s;
    io::ScanMeta& m = s.meta;
    m.version = "HSF-OCT-103";
    m.size_x = p.size_x;
    m.size_z = p.size_z;
    m.scale_x_mm = 0.0117187;
    m.scale_z_mm = 0.0038716697599738836;
    m.distance_mm = 0.1234567;
    m.size_x_slo = p.slo_x;
    m.size_y_slo = p.slo_y;
    m.scale_x_slo_mm = 0.0114;
    m.scale_y_slo_mm = 0.0115;
    m.field_size_slo_deg = 30;
    m.scan_focus_dpt = -1.77;
    m.laterality = io::Laterality::kOS;
    m.scan_position_raw = "OS";
    m.pattern = io::ScanPattern::kVolume;
    m.scan_pattern_code = 3;
    m.exam_time_filetime = 131234567890123456ULL;
    m.visit_date_ole = 42746.625;
    m.ids.id = "ID-0123456789ab";
    m.ids.reference_id = "REF-42";
    m.ids.pid = 86;
    m.ids.patient_id = "PATIENT-0001";
    m.ids.dob_ole = 18904.0;
    m.ids.vid = 145;
    m.ids.visit_id = "VISIT-7";
    m.prog_id = "octshape-test 1.0";
    m.bscan_hdr_size = 0;  // let the writer choose
    for (int b = 0; b < p.num_bscans; ++b) {
        io::BScan bs;
        bs.version = "HSF-BS-103";
        bs.start_x_mm = 1.0 + 0.01 * b;
        bs.start_y_mm = 2.0 + 0.1234 * b;
        bs.end_x_mm = 9.5 - 0.01 * b;
        bs.end_y_mm = 2.0 + 0.1234 * b + 1e-3;
        bs.off_seg = 256;
        bs.quality = 25.5F + static_cast<float>(b);
        bs.shift = -9 + b;
        for (std::size_t i = 0; i < 6; ++i) bs.iv_trafo[i] = 0.5F * static_cast<float>(i + 1) - b;
        bs.seg.resize(static_cast<std::size_t>(p.num_lines));
        for (int k = 0; k < p.num_lines; ++k) {
            auto& line = bs.seg[static_cast<std::size_t>(k)];
            line.resize(static_cast<std::size_t>(p.size_x));
            for (int a = 0; a < p.size_x; ++a) {
                const bool missing = (a + k + b) % 7 == 0;
                line[static_cast<std::size_t>(a)] =
                    missing ? std::numeric_limits<float>::quiet_NaN()
                            : 0.3F + static_cast<float>(k) * 0.61F +
                                  static_cast<float>(a) * 0.017F + static_cast<float>(b) * 0.1F;
            }
        }
        if (p.pixels) {
            bs.pixels.resize(static_cast<std::size_t>(p.size_x) *
                             static_cast<std::size_t>(p.size_z));
            for (std::size_t i = 0; i < bs.pixels.size(); ++i) {
                bs.pixels[i] = (i % 97 == 5) ? io::kNoPixelData
                                             : static_cast<float>((i * 7919 + b) % 1000) / 999.0F;
            }
        }
        s.bscans.push_back(std::move(bs));
    }
    if (p.pixels) {
        s.slo.resize(static_cast<std::size_t>(p.slo_x) * static_cast<std::size_t>(p.slo_y));
        for (std::size_t i = 0; i < s.slo.size(); ++i)
            s.slo[i] = static_cast<std::uint8_t>(i * 37 + 11);
        s.pixels_loaded = true;
    }
    return s;
}

inline io::ThicknessGrid make_circular_grid(bool from_header) {
    io::ThicknessGrid g;
    g.type = 3;
    g.from_header = from_header;
    g.diameters_mm = {1.0, 3.0, 6.0};
    g.centre_x_slo_mm = 4.25;
    g.centre_y_slo_mm = 4.5;
    g.central_thickness_mm = 0.2178F;
    g.min_central_thickness_mm = 0.2143F;
    g.max_central_thickness_mm = 0.3503F;
    g.total_volume_mm3 = std::numeric_limits<float>::quiet_NaN();
    g.cells.resize(9);
    for (std::size_t i = 0; i < 9; ++i) {
        g.cells[i].thickness_mm = i == 4 ? std::numeric_limits<float>::quiet_NaN()
                                         : 0.25F + 0.01F * static_cast<float>(i);
        g.cells[i].volume_mm3 = 0.1F * static_cast<float>(i);
    }
    return g;
}

inline io::ThicknessGrid make_rect_grid() {
    io::ThicknessGrid g;
    g.type = 9;
    g.from_header = true;
    g.rows = 3;
    g.cols = 4;
    g.cell_width_mm = 0.5F;
    g.cell_height_mm = 0.75F;
    g.tilt = 0.125F;
    g.centre_x_slo_mm = 3.5;
    g.centre_y_slo_mm = 4.0;
    g.cells.resize(12);
    for (std::size_t i = 0; i < 12; ++i) {
        g.cells[i].thickness_mm = 0.3F + 0.001F * static_cast<float>(i);
        g.cells[i].volume_mm3 = i == 7 ? std::numeric_limits<float>::quiet_NaN() : 0.02F;
    }
    return g;
}

// Bitwise float equality, with every NaN equal to every NaN (missing == missing).
inline bool same_float(float a, float b) {
    if (std::isnan(a) || std::isnan(b)) return std::isnan(a) && std::isnan(b);
    return std::bit_cast<std::uint32_t>(a) == std::bit_cast<std::uint32_t>(b);
}
inline bool same_double(double a, double b) {
    return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}

// Every grid field equal (file_offset is compared by the caller where it is known).
inline void expect_same_grid(const io::ThicknessGrid& a, const io::ThicknessGrid& b) {
    EXPECT_EQ(a.type, b.type);
    EXPECT_EQ(a.from_header, b.from_header);
    for (std::size_t i = 0; i < 3; ++i)
        EXPECT_TRUE(same_double(a.diameters_mm[i], b.diameters_mm[i]));
    EXPECT_TRUE(same_double(a.centre_x_slo_mm, b.centre_x_slo_mm));
    EXPECT_TRUE(same_double(a.centre_y_slo_mm, b.centre_y_slo_mm));
    EXPECT_TRUE(same_float(a.central_thickness_mm, b.central_thickness_mm));
    EXPECT_TRUE(same_float(a.min_central_thickness_mm, b.min_central_thickness_mm));
    EXPECT_TRUE(same_float(a.max_central_thickness_mm, b.max_central_thickness_mm));
    EXPECT_TRUE(same_float(a.total_volume_mm3, b.total_volume_mm3));
    EXPECT_EQ(a.rows, b.rows);
    EXPECT_EQ(a.cols, b.cols);
    EXPECT_TRUE(same_float(a.cell_width_mm, b.cell_width_mm));
    EXPECT_TRUE(same_float(a.cell_height_mm, b.cell_height_mm));
    EXPECT_TRUE(same_float(a.tilt, b.tilt));
    ASSERT_EQ(a.cells.size(), b.cells.size());
    for (std::size_t i = 0; i < a.cells.size(); ++i) {
        EXPECT_TRUE(same_float(a.cells[i].thickness_mm, b.cells[i].thickness_mm)) << "cell " << i;
        EXPECT_TRUE(same_float(a.cells[i].volume_mm3, b.cells[i].volume_mm3)) << "cell " << i;
    }
}

// Every field the .vol format stores, compared exactly. bscan_hdr_size and grid offsets are
// derived by the writer and compared by the caller. Pixels and SLO only when `with_pixels`.
inline void expect_same_scan(const io::Scan& a, const io::Scan& b, bool with_pixels) {
    const io::ScanMeta& x = a.meta;
    const io::ScanMeta& y = b.meta;
    EXPECT_EQ(x.format, y.format);
    EXPECT_EQ(x.version, y.version);
    EXPECT_EQ(x.size_x, y.size_x);
    EXPECT_EQ(x.size_z, y.size_z);
    EXPECT_TRUE(same_double(x.scale_x_mm, y.scale_x_mm));
    EXPECT_TRUE(same_double(x.scale_z_mm, y.scale_z_mm));
    EXPECT_TRUE(same_double(x.distance_mm, y.distance_mm));
    EXPECT_EQ(x.size_x_slo, y.size_x_slo);
    EXPECT_EQ(x.size_y_slo, y.size_y_slo);
    EXPECT_TRUE(same_double(x.scale_x_slo_mm, y.scale_x_slo_mm));
    EXPECT_TRUE(same_double(x.scale_y_slo_mm, y.scale_y_slo_mm));
    EXPECT_EQ(x.field_size_slo_deg, y.field_size_slo_deg);
    EXPECT_TRUE(same_double(x.scan_focus_dpt, y.scan_focus_dpt));
    EXPECT_EQ(x.laterality, y.laterality);
    EXPECT_EQ(x.scan_position_raw, y.scan_position_raw);
    EXPECT_EQ(x.pattern, y.pattern);
    EXPECT_EQ(x.scan_pattern_code, y.scan_pattern_code);
    EXPECT_EQ(x.exam_time_filetime, y.exam_time_filetime);
    EXPECT_EQ(x.visit_date_ole, y.visit_date_ole);
    EXPECT_EQ(x.ids.id, y.ids.id);
    EXPECT_EQ(x.ids.reference_id, y.ids.reference_id);
    EXPECT_EQ(x.ids.pid, y.ids.pid);
    EXPECT_EQ(x.ids.patient_id, y.ids.patient_id);
    EXPECT_EQ(x.ids.dob_ole, y.ids.dob_ole);
    EXPECT_EQ(x.ids.vid, y.ids.vid);
    EXPECT_EQ(x.ids.visit_id, y.ids.visit_id);
    EXPECT_EQ(x.prog_id, y.prog_id);
    ASSERT_EQ(a.bscans.size(), b.bscans.size());
    for (std::size_t i = 0; i < a.bscans.size(); ++i) {
        SCOPED_TRACE("B-scan " + std::to_string(i));
        const io::BScan& p = a.bscans[i];
        const io::BScan& q = b.bscans[i];
        EXPECT_EQ(p.version, q.version);
        EXPECT_TRUE(same_double(p.start_x_mm, q.start_x_mm));
        EXPECT_TRUE(same_double(p.start_y_mm, q.start_y_mm));
        EXPECT_TRUE(same_double(p.end_x_mm, q.end_x_mm));
        EXPECT_TRUE(same_double(p.end_y_mm, q.end_y_mm));
        EXPECT_EQ(p.off_seg, q.off_seg);
        EXPECT_TRUE(same_float(p.quality, q.quality));
        EXPECT_EQ(p.shift, q.shift);
        for (std::size_t t = 0; t < 6; ++t) EXPECT_TRUE(same_float(p.iv_trafo[t], q.iv_trafo[t]));
        EXPECT_EQ(p.bmo.has_value(), q.bmo.has_value());
        if (p.bmo && q.bmo) {
            EXPECT_EQ(p.bmo->left, q.bmo->left);
            EXPECT_EQ(p.bmo->right, q.bmo->right);
        }
        ASSERT_EQ(p.seg.size(), q.seg.size());
        std::size_t seg_diff = 0;
        for (std::size_t k = 0; k < p.seg.size(); ++k) {
            ASSERT_EQ(p.seg[k].size(), q.seg[k].size());
            for (std::size_t j = 0; j < p.seg[k].size(); ++j) {
                seg_diff += same_float(p.seg[k][j], q.seg[k][j]) ? 0U : 1U;
            }
        }
        EXPECT_EQ(seg_diff, 0U);
        if (with_pixels) {
            ASSERT_EQ(p.pixels.size(), q.pixels.size());
            std::size_t px_diff = 0;
            for (std::size_t j = 0; j < p.pixels.size(); ++j) {
                px_diff += same_float(p.pixels[j], q.pixels[j]) ? 0U : 1U;
            }
            EXPECT_EQ(px_diff, 0U);
        }
    }
    if (with_pixels) {
        EXPECT_EQ(a.slo, b.slo);
    }
    ASSERT_EQ(a.grids.size(), b.grids.size());
    for (std::size_t i = 0; i < a.grids.size(); ++i) expect_same_grid(a.grids[i], b.grids[i]);
}

inline std::string write_to_string(const io::Scan& s) {
    std::ostringstream out(std::ios::binary);
    io::write_vol(s, out);
    return out.str();
}

inline io::Scan read_from_string(const std::string& bytes,
                                 bool pixels,
                                 const std::string& name = "mem.vol") {
    std::istringstream in(bytes, std::ios::binary);
    io::ReadOptions opt;
    opt.pixels = pixels;
    return io::read_vol(in, bytes.size(), name, opt);
}

// The whole file as bytes.
inline std::string slurp(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::string bytes(static_cast<std::size_t>(std::filesystem::file_size(p)), '\0');
    in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    EXPECT_TRUE(in.good()) << p;
    return bytes;
}

// Little-endian patching of a file image.
inline void put_u32(std::string& f, std::size_t off, std::uint32_t v) {
    for (std::size_t i = 0; i < 4; ++i) f[off + i] = static_cast<char>((v >> (8 * i)) & 0xFFU);
}
inline void put_i32(std::string& f, std::size_t off, std::int32_t v) {
    put_u32(f, off, std::bit_cast<std::uint32_t>(v));
}
inline void put_f32(std::string& f, std::size_t off, float v) {
    put_u32(f, off, std::bit_cast<std::uint32_t>(v));
}
inline void put_u64(std::string& f, std::size_t off, std::uint64_t v) {
    put_u32(f, off, static_cast<std::uint32_t>(v));
    put_u32(f, off + 4, static_cast<std::uint32_t>(v >> 32));
}
inline void put_f64(std::string& f, std::size_t off, double v) {
    put_u64(f, off, std::bit_cast<std::uint64_t>(v));
}
inline std::uint32_t get_u32(const std::string& f, std::size_t off) {
    std::uint32_t v = 0;
    for (std::size_t i = 0; i < 4; ++i) {
        v |= static_cast<std::uint32_t>(static_cast<unsigned char>(f[off + i])) << (8 * i);
    }
    return v;
}
inline float get_f32(const std::string& f, std::size_t off) {
    return std::bit_cast<float>(get_u32(f, off));
}
inline double get_f64(const std::string& f, std::size_t off) {
    const std::uint64_t lo = get_u32(f, off);
    const std::uint64_t hi = get_u32(f, off + 4);
    return std::bit_cast<double>(lo | (hi << 32));
}

}  // namespace octshape::test
