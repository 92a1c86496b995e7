#include "octshape/io/image.h"

#include <tiffio.h>
#include <zlib.h>

#include <array>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <memory>

#include "octshape/error.h"

namespace octshape::io {
namespace {

// ---- PNG (ISO/IEC 15948) ---------------------------------------------------------------------

void put_u32(std::string& out, std::uint32_t v) {
    for (int s = 24; s >= 0; s -= 8) out.push_back(static_cast<char>((v >> s) & 0xFFU));
}

// A chunk: length, type, data, CRC-32 of type and data.
void put_chunk(std::string& out, const char* type, const std::string& data) {
    put_u32(out, static_cast<std::uint32_t>(data.size()));
    const std::size_t start = out.size();
    out.append(type, 4);
    out += data;
    const auto* p = reinterpret_cast<const Bytef*>(out.data() + start);
    put_u32(out, static_cast<std::uint32_t>(
                     crc32(0L, p, static_cast<uInt>(out.size() - start))));
}

int paeth(int a, int b, int c) {
    const int p = a + b - c;
    const int pa = std::abs(p - a);
    const int pb = std::abs(p - b);
    const int pc = std::abs(p - c);
    if (pa <= pb && pa <= pc) return a;
    return pb <= pc ? b : c;
}

// ---- TIFF ------------------------------------------------------------------------------------

// libtiff reports through handlers; these keep its first error for our message and keep
// stderr clean (the default handlers print).
int keep_first_error(TIFF* /*tif*/, void* user, const char* module, const char* fmt,
                     va_list ap) {
    auto* first = static_cast<std::string*>(user);
    if (first->empty()) {
        std::array<char, 256> buf{};
        std::vsnprintf(buf.data(), buf.size(), fmt, ap);
        *first = (module != nullptr ? std::string(module) + ": " : std::string()) + buf.data();
    }
    return 1;
}
int ignore_warning(TIFF*, void*, const char*, const char*, va_list) { return 1; }

struct TiffCloser {
    void operator()(TIFF* t) const { TIFFClose(t); }
};

}  // namespace

std::string encode_png(int width, int height, int channels, std::span<const std::uint8_t> pixels) {
    if (width <= 0 || height <= 0 || (channels != 1 && channels != 3) ||
        pixels.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height) *
                             static_cast<std::size_t>(channels)) {
        throw DataError("encode_png: the pixels do not match width x height x channels");
    }
    const std::size_t row = static_cast<std::size_t>(width) * static_cast<std::size_t>(channels);
    const auto bpp = static_cast<std::size_t>(channels);
    // Filtered rows: for each row the filter with the least sum of |signed residuals| (the
    // heuristic of the PNG specification, section 12.8).
    std::string raw;
    raw.reserve((row + 1) * static_cast<std::size_t>(height));
    std::array<std::string, 5> cand;
    for (auto& c : cand) c.resize(row);
    const std::vector<std::uint8_t> zero(row, 0);
    for (int y = 0; y < height; ++y) {
        const std::uint8_t* cur = pixels.data() + static_cast<std::size_t>(y) * row;
        const std::uint8_t* up = y > 0 ? cur - row : zero.data();
        long best_sum = -1;
        int best = 0;
        for (int f = 0; f < 5; ++f) {
            long sum = 0;
            for (std::size_t i = 0; i < row; ++i) {
                const int a = i >= bpp ? cur[i - bpp] : 0;
                const int b = up[i];
                const int c = i >= bpp ? up[i - bpp] : 0;
                const int pred = f == 0 ? 0 : f == 1 ? a : f == 2 ? b : f == 3 ? (a + b) / 2
                                                                               : paeth(a, b, c);
                const auto v = static_cast<std::uint8_t>(cur[i] - pred);
                cand[static_cast<std::size_t>(f)][i] = static_cast<char>(v);
                sum += v < 128 ? v : 256 - v;
            }
            if (best_sum < 0 || sum < best_sum) {
                best_sum = sum;
                best = f;
            }
        }
        raw.push_back(static_cast<char>(best));
        raw += cand[static_cast<std::size_t>(best)];
    }
    uLongf size = compressBound(static_cast<uLong>(raw.size()));
    std::string idat(size, '\0');
    if (compress2(reinterpret_cast<Bytef*>(idat.data()), &size,
                  reinterpret_cast<const Bytef*>(raw.data()), static_cast<uLong>(raw.size()),
                  6) != Z_OK) {
        // compressBound sizes the buffer, so only zlib running out of memory gets here.
        throw InternalError("encode_png: zlib compression failed");
    }
    idat.resize(size);
    std::string out("\x89PNG\r\n\x1a\n", 8);
    std::string ihdr;
    put_u32(ihdr, static_cast<std::uint32_t>(width));
    put_u32(ihdr, static_cast<std::uint32_t>(height));
    ihdr.push_back(8);                                  // bit depth
    ihdr.push_back(static_cast<char>(channels == 3 ? 2 : 0));  // colour type: RGB or grey
    ihdr.append(3, '\0');  // deflate, adaptive filtering, no interlace
    put_chunk(out, "IHDR", ihdr);
    put_chunk(out, "IDAT", idat);
    put_chunk(out, "IEND", "");
    return out;
}

std::vector<std::uint8_t> read_tiff_gray(const std::string& path,
                                         int width,
                                         int height,
                                         const std::string& context) {
    std::string first_error;
    TIFFOpenOptions* opts = TIFFOpenOptionsAlloc();
    if (opts == nullptr) throw std::bad_alloc();
    TIFFOpenOptionsSetErrorHandlerExtR(opts, keep_first_error, &first_error);
    TIFFOpenOptionsSetWarningHandlerExtR(opts, ignore_warning, nullptr);
    // No single allocation of libtiff beyond what the largest allowed image needs.
    TIFFOpenOptionsSetMaxSingleMemAlloc(opts, tmsize_t{256} << 20);
    const std::unique_ptr<TIFF, TiffCloser> tif(TIFFOpenExt(path.c_str(), "r", opts));
    TIFFOpenOptionsFree(opts);
    const auto unreadable = [&](const std::string& what) {
        return InputError::corrupt(path, "not a readable image (" +
                                             (first_error.empty() ? what : first_error) + ")" +
                                             context);
    };
    if (!tif) throw unreadable("not a TIFF file");
    std::uint32_t w = 0;
    std::uint32_t h = 0;
    if (TIFFGetField(tif.get(), TIFFTAG_IMAGEWIDTH, &w) != 1 ||
        TIFFGetField(tif.get(), TIFFTAG_IMAGELENGTH, &h) != 1) {
        throw unreadable("no image size");
    }
    if (w != static_cast<std::uint32_t>(width) || h != static_cast<std::uint32_t>(height)) {
        throw InputError::corrupt(path, "image is " + std::to_string(w) + "x" + std::to_string(h) +
                                            ", the XML says " + std::to_string(width) + "x" +
                                            std::to_string(height) + context);
    }
    std::uint16_t bits = 0;
    std::uint16_t samples = 0;
    std::uint16_t photometric = 0;
    TIFFGetFieldDefaulted(tif.get(), TIFFTAG_BITSPERSAMPLE, &bits);
    TIFFGetFieldDefaulted(tif.get(), TIFFTAG_SAMPLESPERPIXEL, &samples);
    const bool has_photometric = TIFFGetField(tif.get(), TIFFTAG_PHOTOMETRIC, &photometric) == 1;
    const auto n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
    std::vector<std::uint8_t> out(n);
    if (bits == 8 && samples == 1 && has_photometric && photometric == PHOTOMETRIC_MINISBLACK &&
        TIFFIsTiled(tif.get()) == 0 &&
        TIFFScanlineSize(tif.get()) == static_cast<tmsize_t>(width)) {
        for (int r = 0; r < height; ++r) {
            if (TIFFReadScanline(tif.get(), out.data() + static_cast<std::size_t>(r) *
                                                             static_cast<std::size_t>(width),
                                 static_cast<std::uint32_t>(r), 0) != 1) {
                throw unreadable("row " + std::to_string(r) + " unreadable");
            }
        }
        return out;
    }
    std::vector<std::uint32_t> rgba(n);
    if (TIFFReadRGBAImageOriented(tif.get(), w, h, rgba.data(), ORIENTATION_TOPLEFT, 0) != 1) {
        throw unreadable("pixels unreadable");
    }
    for (std::size_t i = 0; i < n; ++i) {
        const std::uint32_t p = rgba[i];
        out[i] = static_cast<std::uint8_t>(
            (299U * TIFFGetR(p) + 587U * TIFFGetG(p) + 114U * TIFFGetB(p) + 500U) / 1000U);
    }
    return out;
}

}  // namespace octshape::io
