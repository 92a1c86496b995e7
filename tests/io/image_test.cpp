// io/image.h against OpenCV's codecs (linked into the tests only): our PNGs decode to the
// pixels encoded, and our TIFF reading gives OpenCV's grey levels on the Heyex export's images.
#include "octshape/io/image.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <string>
#include <vector>

#include "octshape/error.h"
#include "test_paths.h"

namespace octshape::io {
namespace {

namespace fs = std::filesystem;

// Pixels with every kind of content a QC picture has: flat areas, gradients, noise.
std::vector<std::uint8_t> test_pixels(int w, int h, int channels, unsigned seed) {
    std::mt19937 rng(seed);
    std::vector<std::uint8_t> px(static_cast<std::size_t>(w * h * channels));
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            for (int c = 0; c < channels; ++c) {
                const auto i = static_cast<std::size_t>((y * w + x) * channels + c);
                if (x < w / 3) {
                    px[i] = static_cast<std::uint8_t>(40 * c + 7);
                } else if (x < 2 * w / 3) {
                    px[i] = static_cast<std::uint8_t>(3 * x + 5 * y + 50 * c);
                } else {
                    px[i] = static_cast<std::uint8_t>(rng() & 0xFFU);
                }
            }
        }
    }
    return px;
}

cv::Mat decode(const std::string& png) {
    const std::vector<std::uint8_t> buf(png.begin(), png.end());
    return cv::imdecode(buf, cv::IMREAD_UNCHANGED);
}

TEST(Png, GreyAndColourDecodeToTheEncodedPixels) {
    for (const auto& [w, h] : {std::pair{1, 1}, std::pair{7, 5}, std::pair{64, 33},
                               std::pair{301, 2}}) {
        for (const int channels : {1, 3}) {
            const auto px = test_pixels(w, h, channels, static_cast<unsigned>(w * 31 + h));
            const std::string png = encode_png(w, h, channels, px);
            ASSERT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
            cv::Mat m = decode(png);
            ASSERT_FALSE(m.empty()) << w << "x" << h << "x" << channels;
            ASSERT_EQ(m.cols, w);
            ASSERT_EQ(m.rows, h);
            ASSERT_EQ(m.channels(), channels);
            ASSERT_EQ(m.depth(), CV_8U);
            if (channels == 3) cv::cvtColor(m, m, cv::COLOR_BGR2RGB);
            const std::vector<std::uint8_t> got(m.data, m.data + m.total() * m.elemSize());
            EXPECT_EQ(got, px) << w << "x" << h << "x" << channels;
        }
    }
}

TEST(Png, SmoothPicturesCompress) {
    // A gradient is what the row filters are for: filtered, every residual is 3 or 5, and the
    // file is a small fraction of the raw bytes (unfiltered, deflate sees 256-byte periods).
    const int w = 512;
    const int h = 256;
    std::vector<std::uint8_t> px(static_cast<std::size_t>(w * h));
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) px[static_cast<std::size_t>(y * w + x)] = static_cast<std::uint8_t>(3 * x + 5 * y);
    }
    EXPECT_LT(encode_png(w, h, 1, px).size(), px.size() / 50);
}

TEST(Png, SizeMismatchIsRefused) {
    const std::vector<std::uint8_t> px(10);
    EXPECT_THROW((void)encode_png(3, 3, 1, px), octshape::DataError);
    EXPECT_THROW((void)encode_png(5, 2, 2, px), octshape::DataError);
    EXPECT_THROW((void)encode_png(0, 2, 1, {}), octshape::DataError);
}

fs::path dummy_export() { return test::shared_dir() / "realdata" / "heyex_xml_dummy"; }

TEST(Tiff, TheExportsImagesReadAsOpenCvReadsThem) {
    SKIP_UNLESS_SHARED("realdata/heyex_xml_dummy");
    int checked = 0;
    for (const auto& e : fs::directory_iterator(dummy_export())) {
        if (e.path().extension() != ".tif") continue;
        const cv::Mat ref = cv::imread(e.path().string(), cv::IMREAD_GRAYSCALE);
        ASSERT_FALSE(ref.empty()) << e.path();
        const auto got = read_tiff_gray(e.path().string(), ref.cols, ref.rows, "");
        const std::vector<std::uint8_t> want(ref.data, ref.data + ref.total());
        EXPECT_EQ(got, want) << e.path();
        ++checked;
    }
    EXPECT_GE(checked, 12);  // B1..B11 and NIR1
}

TEST(Tiff, ColourAndSixteenBitGoThroughRgba) {
    test::TempDir dir;
    const cv::Mat rgb(23, 31, CV_8UC3);
    std::mt19937 rng(5);
    for (std::size_t i = 0; i < rgb.total() * 3; ++i) rgb.data[i] = static_cast<std::uint8_t>(rng());
    const auto p8 = (dir / "rgb.tif").string();
    ASSERT_TRUE(cv::imwrite(p8, rgb));
    const cv::Mat ref = cv::imread(p8, cv::IMREAD_GRAYSCALE);
    const auto got = read_tiff_gray(p8, 31, 23, "");
    ASSERT_EQ(got.size(), ref.total());
    // OpenCV weighs with 14-bit fixed-point coefficients, we with 1/1000 ones: both round
    // 0.299 R + 0.587 G + 0.114 B, so they may differ by one grey level at a .5 boundary.
    for (std::size_t i = 0; i < got.size(); ++i) {
        ASSERT_LE(std::abs(int{got[i]} - int{ref.data[i]}), 1) << i;
    }
    // 16-bit grey: libtiff's RGBA interface scales to 8 bits (v >> 8 on Debian's libtiff);
    // a value v * 257 must come back as v.
    cv::Mat g16(9, 13, CV_16UC1);
    for (int i = 0; i < 9 * 13; ++i) g16.at<std::uint16_t>(i / 13, i % 13) = static_cast<std::uint16_t>(257 * (i * 2 % 256));
    const auto p16 = (dir / "g16.tif").string();
    ASSERT_TRUE(cv::imwrite(p16, g16));
    const auto g = read_tiff_gray(p16, 13, 9, "");
    for (int i = 0; i < 9 * 13; ++i) EXPECT_EQ(g[static_cast<std::size_t>(i)], i * 2 % 256) << i;
}

void expect_unreadable(const std::string& path, const std::string& what) {
    try {
        (void)read_tiff_gray(path, 50, 40, " (image of x.xml)");
        ADD_FAILURE() << "no error for " << what;
    } catch (const InputError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find(path), std::string::npos) << m;
        EXPECT_NE(m.find("(image of x.xml)"), std::string::npos) << m;
        EXPECT_EQ(m.find('\n'), std::string::npos) << m;  // one line
    }
}

TEST(Tiff, TruncatedCorruptAndForeignFilesAreNamedErrors) {
    SKIP_UNLESS_SHARED("realdata/heyex_xml_dummy");
    test::TempDir dir;
    const std::string bytes = test::slurp(dummy_export() / "B1.tif");
    ASSERT_GT(bytes.size(), 2000U);  // 50 x 40 pixels after the header
    const auto write = [&](const std::string& name, const std::string& content) {
        const auto p = (dir / name).string();
        std::ofstream(p, std::ios::binary) << content;
        return p;
    };
    // The pixels cut off half-way: the strip cannot be read.
    expect_unreadable(write("cut.tif", bytes.substr(0, 256 + 1000)), "a truncated strip");
    // Only the header: the directory (at the end of this file) is gone.
    expect_unreadable(write("head.tif", bytes.substr(0, 8)), "a header only");
    expect_unreadable(write("text.tif", "this is not an image\n"), "a text file");
    expect_unreadable(write("empty.tif", ""), "an empty file");
    // The strip's offset moved beyond the end of the file.
    std::string moved = bytes;
    const auto at = moved.find(std::string("\x11\x01\x04\x00\x01\x00\x00\x00", 8));  // StripOffsets
    ASSERT_NE(at, std::string::npos);
    moved[at + 8] = '\x00';
    moved[at + 9] = '\x00';
    moved[at + 10] = '\x00';
    moved[at + 11] = '\x70';
    expect_unreadable(write("moved.tif", moved), "a strip beyond the end of the file");
    // The wrong size is refused before the pixels are read.
    try {
        (void)read_tiff_gray((dummy_export() / "B1.tif").string(), 40, 50, "");
        ADD_FAILURE() << "no error for the wrong size";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("image is 50x40, the XML says 40x50"),
                  std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace octshape::io
