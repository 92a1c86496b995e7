#pragma once
// 8-bit raster images without OpenCV's image codecs (whose Debian build loads GDAL and ~140
// shared libraries into every process): PNG encoding for the QC pictures (zlib) and TIFF
// decoding for the B-scan images of a Heyex XML export (libtiff).

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace octshape::io {

// PNG file bytes of a `width` x `height` image, row-major, `channels` = 1 (grey) or 3 (RGB)
// bytes per pixel; each row filtered by the usual minimum-sum-of-differences choice among the
// five PNG filters, zlib level 6. Error (an internal error: the caller's sizes disagree) on a size mismatch.
[[nodiscard]] std::string encode_png(int width,
                                     int height,
                                     int channels,
                                     std::span<const std::uint8_t> pixels);

// The grey levels of the TIFF image at `path`, which must be `width` x `height` (checked from
// its header before any pixel is read): row-major bytes. 8-bit grey images are read as they
// are; any other layout libtiff reads (RGB, palette, 16 bit, tiles, MinIsWhite) through its RGBA
// interface, grey = (299 R + 587 G + 114 B + 500) / 1000. InputError naming the file (and
// `context`, e.g. " (image of scan.xml)") when it is missing, unreadable, corrupt or of another
// size.
[[nodiscard]] std::vector<std::uint8_t> read_tiff_gray(const std::string& path,
                                                       int width,
                                                       int height,
                                                       const std::string& context);

}  // namespace octshape::io
