// read_scan_hashed: the scan and the SHA-256 of the same bytes. Both must be exactly what the
// separate readers give (read_scan, sha256_file), on real and synthetic files; a damaged file
// must fail with the same InputError as read_scan, and a file that changes while it is read
// (truncated, rewritten) must give a typed error, never a signal or a result under a wrong hash.

#include "octshape/io/scan_reader.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "io/vol_test_util.h"
#include "octshape/error.h"
#include "octshape/io/sha256.h"
#include "test_paths.h"

namespace octshape::test {
namespace {

// Same floats bit for bit (NaN = missing compares equal to NaN).
bool same_values(const std::vector<float>& a, const std::vector<float>& b) {
    if (a.size() != b.size()) return false;
    return a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

void expect_same_scan(const io::Scan& a, const io::Scan& b) {
    ASSERT_EQ(a.num_bscans(), b.num_bscans());
    EXPECT_EQ(a.meta.size_x, b.meta.size_x);
    EXPECT_EQ(a.meta.size_z, b.meta.size_z);
    EXPECT_EQ(a.meta.scale_x_mm, b.meta.scale_x_mm);
    EXPECT_EQ(a.meta.laterality, b.meta.laterality);
    EXPECT_EQ(a.grids.size(), b.grids.size());
    EXPECT_EQ(a.source_path, b.source_path);
    for (std::size_t i = 0; i < a.bscans.size(); ++i) {
        ASSERT_EQ(a.bscans[i].seg.size(), b.bscans[i].seg.size());
        for (std::size_t k = 0; k < a.bscans[i].seg.size(); ++k) {
            EXPECT_TRUE(same_values(a.bscans[i].seg[k], b.bscans[i].seg[k])) << i << " " << k;
        }
        EXPECT_TRUE(same_values(a.bscans[i].pixels, b.bscans[i].pixels)) << i;
    }
}

TEST(ReadScanHashed, RealFilesGiveTheSameScanAndHashAsTheSeparateReaders) {
    SKIP_UNLESS_SHARED("realdata/fovea_line_716_0.vol", "realdata/onh_circle_716_2.vol", "realdata/onh_circle_valid.vol");
    for (const char* name :
         {"fovea_line_716_0.vol", "onh_circle_716_2.vol", "onh_circle_valid.vol"}) {
        const std::string path = realdata(name).string();
        for (const bool pixels : {false, true}) {
            const io::HashedScan h = io::read_scan_hashed(path, {.pixels = pixels});
            EXPECT_EQ(h.sha256, io::sha256_file(path)) << name;
            expect_same_scan(h.scan, io::read_scan(path, {.pixels = pixels}));
        }
    }
}

TEST(ReadScanHashed, XmlExportHashesItsXmlFile) {
    SKIP_UNLESS_SHARED("realdata/heyex_xml_dummy");
    const auto dir = realdata("heyex_xml_dummy");
    std::string xml;
    for (const auto& e : std::filesystem::directory_iterator(dir)) {
        if (e.path().extension() == ".xml") xml = e.path().string();
    }
    ASSERT_FALSE(xml.empty());
    const io::HashedScan h = io::read_scan_hashed(xml);
    EXPECT_EQ(h.sha256, io::sha256_file(xml));
    expect_same_scan(h.scan, io::read_scan(xml));
}

TEST(ReadScanHashed, FilesLargerThanTheReleaseChunkReadExactly) {
    // read_scan_hashed hashes the mapping in 8 MiB chunks and releases the pages behind the
    // hash and behind the parser; released pages are mapped again from the page cache when
    // read. A ~26 MiB volume crosses several chunk boundaries in both passes: hash and scan
    // must still be exactly those of the separate readers.
    TempDir tmp;
    const std::string bytes = write_to_string(make_synthetic_scan({.num_bscans = 40,
                                                                   .size_x = 320,
                                                                   .size_z = 512,
                                                                   .num_lines = 3,
                                                                   .slo_x = 64,
                                                                   .slo_y = 64}));
    ASSERT_GT(bytes.size(), std::size_t{3} * (std::size_t{8} << 20U));
    const std::string path = (tmp.path() / "large.vol").string();
    std::ofstream(path, std::ios::binary) << bytes;
    const io::HashedScan h = io::read_scan_hashed(path, {.pixels = true});
    EXPECT_EQ(h.sha256, io::sha256_hex(bytes));
    expect_same_scan(h.scan, io::read_scan(path, {.pixels = true}));
}

TEST(ReadScanHashed, TruncatedAndMissingFilesFailAsReadScanDoes) {
    TempDir tmp;
    const std::string bytes = write_to_string(make_synthetic_scan(
        {.num_bscans = 3, .size_x = 16, .size_z = 12, .num_lines = 3, .slo_x = 8, .slo_y = 8}));
    const std::string whole = (tmp.path() / "whole.vol").string();
    std::ofstream(whole, std::ios::binary) << bytes;
    const io::HashedScan h = io::read_scan_hashed(whole);
    EXPECT_EQ(h.sha256, io::sha256_hex(bytes));
    expect_same_scan(h.scan, io::read_scan(whole));

    // Cut inside the last B-scan's pixels, inside the SLO, and inside the file header.
    for (const std::size_t len : {bytes.size() - 1, std::size_t{2100}, std::size_t{100}}) {
        const std::string cut = (tmp.path() / ("cut" + std::to_string(len) + ".vol")).string();
        std::ofstream(cut, std::ios::binary) << bytes.substr(0, len);
        std::string expected;
        try {
            (void)io::read_scan(cut);
        } catch (const InputError& e) {
            expected = e.what();
        }
        ASSERT_FALSE(expected.empty()) << len;
        try {
            (void)io::read_scan_hashed(cut);
            FAIL() << "accepted a file cut at " << len;
        } catch (const InputError& e) {
            EXPECT_EQ(std::string(e.what()), expected);
        }
    }
    EXPECT_THROW((void)io::read_scan_hashed((tmp.path() / "absent.vol").string()), InputError);
}

TEST(ReadScanHashed, AFileTruncatedOrRewrittenWhileReadGivesATypedErrorOrTheRightHash) {
    // A writer thread truncates the file and writes it back whole, again and again, while the
    // main thread reads it: every read must either succeed with the hash of the whole file (it
    // saw one version from start to end) or throw InputError (truncated, or "changed while it
    // was being read"). A memory mapping would die of SIGBUS here; two threads read at once too.
    TempDir tmp;
    const std::string bytes = write_to_string(make_synthetic_scan({.num_bscans = 20,
                                                                   .size_x = 256,
                                                                   .size_z = 256,
                                                                   .num_lines = 3,
                                                                   .slo_x = 64,
                                                                   .slo_y = 64}));
    const std::string path = (tmp.path() / "moving.vol").string();
    std::ofstream(path, std::ios::binary) << bytes;
    const std::string whole_sha = io::sha256_hex(bytes);
    std::atomic<bool> stop{false};
    std::thread writer([&] {
        while (!stop.load()) {
            std::filesystem::resize_file(path, bytes.size() / 3);
            std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
        }
    });
    std::atomic<int> ok{0};
    std::atomic<int> refused{0};
    std::atomic<int> wrong{0};
    const auto reader = [&] {
        for (int i = 0; i < 40; ++i) {
            try {
                const io::HashedScan h = io::read_scan_hashed(path, {.pixels = true});
                if (h.sha256 == whole_sha && h.scan.num_bscans() == 20) {
                    ++ok;
                } else {
                    ++wrong;
                }
            } catch (const InputError&) {
                ++refused;
            }
        }
    };
    std::thread second(reader);
    reader();
    second.join();
    stop = true;
    writer.join();
    EXPECT_EQ(wrong.load(), 0);  // never a result under another version's hash
    EXPECT_EQ(ok.load() + refused.load(), 80);
    // And once the file is still, it reads as always.
    const io::HashedScan h = io::read_scan_hashed(path);
    EXPECT_EQ(h.sha256, whole_sha);
}

}  // namespace
}  // namespace octshape::test
