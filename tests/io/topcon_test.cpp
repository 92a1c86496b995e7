// The Topcon .fda reader (io/topcon.h): the real UK Biobank example
// (../shared/realdata/topcon_ukb_example_min.fda), our writer's round trip, and damaged files:
// truncations and byte mutations of a small written file and of the real one. Each damaged file
// must read cleanly or give an InputError naming the file, never anything else, and no
// allocation beyond what the file's size allows.

#include "octshape/io/topcon.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <iostream>
#include <random>
#include <sstream>

#include "io/alloc_probe.h"
#include "octshape/error.h"
#include "octshape/io/scan_reader.h"
#include "test_paths.h"

namespace octshape::test {
namespace {

const std::string kReal = "topcon_ukb_example_min.fda";

// A small volume with known lines: 16 A-scans x 64 px x 8 B-scans, ILM at 20 + b, BM at 40 + a/4.
io::Scan small_scan() {
    io::Scan s;
    io::ScanMeta& m = s.meta;
    m.size_x = 16;
    m.size_z = 64;
    m.scale_x_mm = 0.375;  // 6 mm / 16
    m.scale_z_mm = 0.0035;
    m.distance_mm = 6.0 / 7.0;
    m.laterality = io::Laterality::kOS;
    m.pattern = io::ScanPattern::kVolume;
    s.bscans.resize(8);
    for (int b = 0; b < 8; ++b) {
        auto& seg = s.bscans[static_cast<std::size_t>(b)].seg;
        seg.assign(2, std::vector<float>(16));
        for (int a = 0; a < 16; ++a) {
            seg[0][static_cast<std::size_t>(a)] = static_cast<float>(20 + b);
            seg[1][static_cast<std::size_t>(a)] = static_cast<float>(40 + a / 4);
        }
    }
    s.bscans[3].seg[0][5] = std::numeric_limits<float>::quiet_NaN();  // a missing value
    return s;
}

std::string small_file() {
    std::ostringstream out(std::ios::binary);
    io::write_topcon(small_scan(), out);
    return out.str();
}

// Reads `bytes` under the allocation probe: true on a clean read, false on an InputError naming
// the file; anything else fails the test. A reader holds the file and the lines: never more than
// a few times the file's size in one allocation (+ 64 KiB for small files).
bool reads(const std::string& bytes, const std::string& label) {
    AllocProbe probe;
    try {
        const io::Scan s = io::parse_topcon(bytes, "hostile.fda");
        EXPECT_LE(probe.largest(), 4 * bytes.size() + 65536) << label;
        for (const auto& b : s.bscans) {
            for (const auto& line : b.seg) {
                for (float v : line) {
                    if (!io::is_valid(v)) continue;
                    EXPECT_TRUE(v >= 0.0F && v < static_cast<float>(s.meta.size_z)) << label;
                }
            }
        }
        EXPECT_TRUE(std::isfinite(s.meta.scale_x_mm) && s.meta.scale_x_mm > 0.0) << label;
        EXPECT_TRUE(std::isfinite(s.meta.scale_z_mm) && s.meta.scale_z_mm > 0.0) << label;
        return true;
    } catch (const InputError& e) {
        EXPECT_LE(probe.largest(), 4 * bytes.size() + 65536) << label;
        EXPECT_EQ(e.path(), "hostile.fda") << label;
        EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << label;
        return false;
    } catch (const std::exception& e) {
        ADD_FAILURE() << label << ": not an InputError: " << e.what();
        return false;
    }
}

TEST(Topcon, RealUkBiobankFileGeometryEyeAndContours) {
    SKIP_UNLESS_SHARED("realdata/topcon_ukb_example_min.fda");
    const std::string path = realdata(kReal).string();
    EXPECT_EQ(io::detect_format(path), io::FileFormat::kTopcon);
    const io::Scan s = io::read_scan(path);
    EXPECT_EQ(s.meta.format, io::SourceFormat::kTopcon);
    EXPECT_NE(s.meta.version.find("3DOCT-1000MK2"), std::string::npos) << s.meta.version;
    // @PARAM_SCAN_04: 6 x 6 mm, 3.5 um pixels; @IMG_JPEG: 512 x 650; 128 contour rows.
    EXPECT_EQ(s.meta.size_x, 512);
    EXPECT_EQ(s.meta.size_z, 650);
    EXPECT_EQ(s.num_bscans(), 128);
    EXPECT_DOUBLE_EQ(s.meta.scale_x_mm, 6.0 / 512);
    EXPECT_DOUBLE_EQ(s.meta.scale_z_mm, 0.0035);
    EXPECT_DOUBLE_EQ(s.meta.distance_mm, 6.0 / 127);
    EXPECT_EQ(s.meta.pattern, io::ScanPattern::kVolume);
    EXPECT_EQ(s.meta.laterality, io::Laterality::kOS);  // @CAPTURE_INFO_02 eye byte 1
    EXPECT_TRUE(s.meta.exam_time_filetime.has_value());
    ASSERT_EQ(s.num_lines(), 4);
    EXPECT_EQ(s.line_name(0), "ILM");
    EXPECT_EQ(s.line_name(1), "BM");
    EXPECT_EQ(s.line_name(2), "RETINA_2");
    EXPECT_EQ(s.line_name(3), "RETINA_3");
    EXPECT_DOUBLE_EQ(s.valid_fraction(0), 1.0);
    EXPECT_DOUBLE_EQ(s.valid_fraction(1), 1.0);
    // The thinnest point, measured on the raw contours independently of this reader
    // (realdata/README.md): RETINA_1 - RETINA_4 = 64 px at B-scan 63, A-scan 251.
    EXPECT_FLOAT_EQ(s.depth_px(1, 63, 251) - s.depth_px(0, 63, 251), 64.0F);
    // Top to bottom everywhere: ILM, RETINA_2, RETINA_3, BM.
    for (int b = 0; b < 128; ++b) {
        for (int a = 0; a < 512; ++a) {
            ASSERT_LE(s.depth_px(0, b, a), s.depth_px(2, b, a));
            ASSERT_LE(s.depth_px(2, b, a), s.depth_px(3, b, a));
            ASSERT_LE(s.depth_px(3, b, a), s.depth_px(1, b, a));
        }
    }
    // The inner RPE boundary as BM on request.
    io::ReadOptions inner;
    inner.iowa_bm = io::IowaBm::kInnerRpe;
    const io::Scan t = io::read_scan(path, inner);
    EXPECT_FLOAT_EQ(t.depth_px(1, 63, 251), s.depth_px(3, 63, 251));
    EXPECT_EQ(t.line_name(2), "RETINA_2");
    EXPECT_EQ(t.line_name(3), "RETINA_4");
}

TEST(Topcon, WriterRoundTrip) {
    const io::Scan in = small_scan();
    const io::Scan out = io::parse_topcon(small_file(), "small.fda");
    EXPECT_EQ(out.meta.size_x, 16);
    EXPECT_EQ(out.meta.size_z, 64);
    EXPECT_EQ(out.num_bscans(), 8);
    EXPECT_NEAR(out.meta.scale_x_mm, in.meta.scale_x_mm, 1e-12);
    EXPECT_NEAR(out.meta.distance_mm, in.meta.distance_mm, 1e-12);
    EXPECT_NEAR(out.meta.scale_z_mm, in.meta.scale_z_mm, 1e-12);
    EXPECT_EQ(out.meta.laterality, io::Laterality::kOS);
    for (int b = 0; b < 8; ++b) {
        for (int a = 0; a < 16; ++a) {
            if (b == 3 && a == 5) {
                EXPECT_FALSE(io::is_valid(out.depth_px(0, b, a)));
                continue;
            }
            EXPECT_EQ(out.depth_px(0, b, a), in.depth_px(0, b, a));
            EXPECT_EQ(out.depth_px(1, b, a), in.depth_px(1, b, a));
            EXPECT_EQ(out.depth_px(2, b, a), in.depth_px(1, b, a) - 12.0F);  // RETINA_3
        }
    }
    // B-scan 0 is the inferior edge: it lies lowest on the fundus (largest y, y down).
    EXPECT_GT(out.bscans.front().start_y_mm, out.bscans.back().start_y_mm);
}

TEST(Topcon, EveryTruncationOfASmallFileIsAnInputError) {
    const std::string base = small_file();
    for (std::size_t n = 0; n < base.size(); ++n) {
        EXPECT_FALSE(reads(base.substr(0, n), "truncated to " + std::to_string(n)));
    }
}

TEST(Topcon, DamagedStructuresNameTheProblemAndItsOffset) {
    const std::string base = small_file();
    // The first chunk (@HW_INFO_03) at 15: name length 11, size at 27, data at 31.
    std::string big = base;
    const std::uint32_t huge = 0xFFFFFFF0U;
    std::memcpy(big.data() + 27, &huge, 4);
    try {
        (void)io::parse_topcon(big, "x.fda");
        ADD_FAILURE() << "read";
    } catch (const InputError& e) {
        EXPECT_EQ(e.kind(), InputError::Kind::kTruncated);
        EXPECT_EQ(e.offset(), std::optional<std::uint64_t>(31));
        EXPECT_NE(e.reason().find("@HW_INFO_03 declares 4294967280 bytes"), std::string::npos)
            << e.what();
    }
    // A NaN scan width in @PARAM_SCAN_04.
    const std::size_t param = base.find("@PARAM_SCAN_04") + 14 + 4;
    std::string nan = base;
    const double q = std::numeric_limits<double>::quiet_NaN();
    std::memcpy(nan.data() + param + 12, &q, 8);
    try {
        (void)io::parse_topcon(nan, "x.fda");
        ADD_FAILURE() << "read";
    } catch (const InputError& e) {
        EXPECT_EQ(e.kind(), InputError::Kind::kCorrupt);
        EXPECT_EQ(e.offset(), std::optional<std::uint64_t>(param + 12));
    }
    // A denormal axial pixel size (found by the fuzzer: it divided down to a zero scale).
    std::string tiny = base;
    const double denormal = 1e-320;
    std::memcpy(tiny.data() + param + 28, &denormal, 8);
    try {
        (void)io::parse_topcon(tiny, "x.fda");
        ADD_FAILURE() << "read";
    } catch (const InputError& e) {
        EXPECT_EQ(e.kind(), InputError::Kind::kCorrupt);
        EXPECT_EQ(e.offset(), std::optional<std::uint64_t>(param + 28));
    }
    // A contour whose stated data size disagrees with its sides.
    const std::size_t contour = base.find("RETINA_1");
    std::string wrong = base;
    const std::uint32_t n = 7;
    std::memcpy(wrong.data() + contour + 30, &n, 4);
    try {
        (void)io::parse_topcon(wrong, "x.fda");
        ADD_FAILURE() << "read";
    } catch (const InputError& e) {
        EXPECT_EQ(e.kind(), InputError::Kind::kCorrupt);
        EXPECT_EQ(e.offset(), std::optional<std::uint64_t>(contour + 30));
    }
    // ILM and BM swapped (RETINA_1 below RETINA_4): refused, not read upside down.
    std::string swapped = base;
    const std::size_t r4 = base.find("RETINA_4");
    std::memcpy(swapped.data() + contour, "RETINA_4", 8);
    std::memcpy(swapped.data() + r4, "RETINA_1", 8);
    EXPECT_FALSE(reads(swapped, "swapped"));
}

TEST(Topcon, RandomMutationsOfASmallFileNeverCrash) {
    const std::string base = small_file();
    std::mt19937_64 rng(20261206);
    std::size_t ok = 0;
    std::size_t errors = 0;
    for (std::size_t i = 0; i < base.size(); ++i) {
        for (const int v : {0x00, 0xFF, static_cast<int>(rng() & 0xFFU)}) {
            if (static_cast<unsigned char>(base[i]) == v) continue;
            std::string f = base;
            f[i] = static_cast<char>(v);
            (reads(f, "byte " + std::to_string(i)) ? ok : errors) += 1;
        }
    }
    for (int t = 0; t < 20000; ++t) {
        std::string f = base;
        const std::size_t n = 1 + rng() % 8;
        for (std::size_t j = 0; j < n; ++j) f[rng() % f.size()] = static_cast<char>(rng() & 0xFFU);
        if (rng() % 4 == 0) f.resize(rng() % f.size());
        (reads(f, "mutation " + std::to_string(t)) ? ok : errors) += 1;
    }
    std::cout << "[ fda mutations ] " << ok + errors << " mutated small files: " << ok
              << " read cleanly, " << errors << " gave InputError, 0 crashes\n";
    EXPECT_GT(ok, 1000U);
    EXPECT_GT(errors, 1000U);
}

// The real file's JPEG 2000 frame (B-scan 0), twice, under a two-B-scan file of our writer:
// (frames, contours) = (B-scan 0 of the real file, its ILM and BM rows 0 and 1).
std::string two_frame_file(const std::string& real, std::string_view frame) {
    const io::Scan r = io::parse_topcon(real, "real.fda");
    io::Scan s;
    s.meta = r.meta;
    s.meta.distance_mm = 0.05;
    s.bscans = {r.bscans[0], r.bscans[0]};
    std::ostringstream out(std::ios::binary);
    io::write_topcon(s, out);
    std::string f = out.str();
    const std::size_t at = f.find("@IMG_JPEG");
    std::string chunk = f.substr(at + 9 + 4, 25);
    const std::uint32_t two = 2;
    std::memcpy(chunk.data() + 17, &two, 4);
    const auto n = static_cast<std::uint32_t>(frame.size());
    for (int k = 0; k < 2; ++k) {
        chunk.append(reinterpret_cast<const char*>(&n), 4);
        chunk.append(frame);
    }
    const auto size = static_cast<std::uint32_t>(chunk.size());
    std::string sized(reinterpret_cast<const char*>(&size), 4);
    return f.substr(0, at + 9) + sized + chunk + f.substr(at + 9 + 4 + 25);
}

TEST(Topcon, JpegFramesDecodedWhenEveryBScanHasOneAndDamagedFramesRefused) {
    SKIP_UNLESS_SHARED("realdata/topcon_ukb_example_min.fda");
    const std::string real = slurp(realdata(kReal));
    // @IMG_JPEG is the real file's 4th chunk: data at 920, frame size at 945, codestream at 949.
    std::uint32_t n = 0;
    std::memcpy(&n, real.data() + 945, 4);
    const std::string_view frame(real.data() + 949, n);
    ASSERT_EQ(static_cast<unsigned char>(frame[0]), 0xFF);
    io::ReadOptions px;
    px.pixels = true;
    // The real file holds 1 frame for 128 B-scans: no pixels, said.
    const io::Scan partial = io::parse_topcon(real, "real.fda", px);
    EXPECT_FALSE(partial.pixels_loaded);
    const io::Scan s = io::parse_topcon(two_frame_file(real, frame), "two.fda", px);
    ASSERT_TRUE(s.pixels_loaded);
    ASSERT_EQ(s.bscans[1].pixels.size(), 512U * 650U);
    // The decoded frame lies under its contours: dark above the ILM, bright below it, bright
    // above BM and darker below (mean over the B-scan, 3 px away; display values^4).
    double above = 0, below = 0, rpe = 0, choroid = 0;
    for (int a = 0; a < 512; ++a) {
        const auto px_at = [&](float depth, int dz) {
            return s.bscans[1].pixels[static_cast<std::size_t>(std::lround(depth) + dz) * 512 +
                                      static_cast<std::size_t>(a)];
        };
        above += px_at(s.depth_px(0, 1, a), -3);
        below += px_at(s.depth_px(0, 1, a), 3);
        rpe += px_at(s.depth_px(1, 1, a), -3);
        choroid += px_at(s.depth_px(1, 1, a), 3);
    }
    EXPECT_GT(below, 10 * above);
    EXPECT_GT(rpe, 2 * choroid);
    // A frame cut to half its codestream, or with its header garbled: refused with the offset.
    for (const std::string& bad :
         {std::string(frame.substr(0, n / 2)), std::string(frame.substr(0, 2)) + "garbage"}) {
        try {
            (void)io::parse_topcon(two_frame_file(real, bad), "bad.fda", px);
            ADD_FAILURE() << "read";
        } catch (const InputError& e) {
            EXPECT_EQ(e.kind(), InputError::Kind::kCorrupt) << e.what();
            EXPECT_NE(e.reason().find("B-scan frame 0"), std::string::npos) << e.what();
        }
        // Without pixels the frames are only framed, not decoded: the file reads.
        EXPECT_NO_THROW((void)io::parse_topcon(two_frame_file(real, bad), "bad.fda"));
    }
}

TEST(Topcon, RealFileTruncatedAtAndAroundEveryChunkIsAnInputError) {
    SKIP_UNLESS_SHARED("realdata/topcon_ukb_example_min.fda");
    const std::string base = slurp(realdata(kReal));
    // Every chunk start, and 1, 2, 5, 17 and 35 bytes into it, and 1 byte before the end.
    std::vector<std::size_t> cuts;
    std::size_t p = 15;
    while (p < base.size() && base[p] != 0) {
        const auto len = static_cast<unsigned char>(base[p]);
        std::uint32_t size = 0;
        std::memcpy(&size, base.data() + p + 1 + len, 4);
        for (const std::size_t d : {0, 1, 2, 5, 17, 35}) cuts.push_back(p + d);
        p += 1U + len + 4U + size;
    }
    std::size_t errors = 0;
    for (const std::size_t n : cuts) errors += reads(base.substr(0, n), std::to_string(n)) ? 0 : 1;
    std::cout << "[ fda real truncations ] " << cuts.size() << " truncations: " << errors
              << " InputError\n";
    EXPECT_EQ(errors, cuts.size());
    // Bytes mutated in every chunk header and in the first bytes of its data.
    std::mt19937_64 rng(7);
    std::size_t ok = 0;
    std::size_t bad = 0;
    for (std::size_t c = 0; c < cuts.size(); c += 6) {
        for (int t = 0; t < 12; ++t) {
            std::string f = base;
            f[cuts[c] + rng() % 60] = static_cast<char>(rng() & 0xFFU);
            (reads(f, "real mutation") ? ok : bad) += 1;
        }
    }
    std::cout << "[ fda real mutations ] " << ok + bad << " mutated: " << ok << " read cleanly, "
              << bad << " InputError, 0 crashes\n";
}

}  // namespace
}  // namespace octshape::test
