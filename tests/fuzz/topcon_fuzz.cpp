// libFuzzer target for the Topcon .fda/.fds reader. Only InputError may come out of
// parse_topcon; a file it accepts must give a scan whose sizes agree with its lines, whose
// depths are NaN or inside the B-scan and whose scales are finite and positive, and that scan
// must go through write_topcon and parse_topcon with its ILM and BM unchanged (a differential
// check of the reader against the writer). Each input is also read with pixels (the JPEG 2000
// frames through OpenJPEG).

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "fuzz_util.h"
#include "octshape/error.h"
#include "octshape/io/topcon.h"

using octshape::fuzz::check;
using octshape::fuzz::same;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view bytes(reinterpret_cast<const char*>(data), size);
    octshape::io::Scan s;
    try {
        s = octshape::io::parse_topcon(bytes, "fuzz.fda");
    } catch (const octshape::InputError&) {
        return 0;  // the expected outcome for damaged input
    }
    // With pixels: the JPEG 2000 frames through OpenJPEG (only InputError may come out).
    try {
        octshape::io::ReadOptions px;
        px.pixels = true;
        const octshape::io::Scan p = octshape::io::parse_topcon(bytes, "fuzz.fda", px);
        if (p.pixels_loaded) {
            for (const auto& b : p.bscans) {
                check(b.pixels.size() == static_cast<std::size_t>(p.meta.size_x) *
                                             static_cast<std::size_t>(p.meta.size_z));
            }
        }
    } catch (const octshape::InputError&) {
    }
    const auto& m = s.meta;
    check(std::isfinite(m.scale_x_mm) && m.scale_x_mm > 0.0);
    check(std::isfinite(m.scale_z_mm) && m.scale_z_mm > 0.0);
    check(std::isfinite(m.distance_mm) && m.distance_mm >= 0.0);
    check(s.num_lines() >= 2);
    for (const auto& b : s.bscans) {
        for (const auto& line : b.seg) {
            check(line.size() == static_cast<std::size_t>(m.size_x));
            for (float v : line) {
                check(std::isnan(v) || (v >= 0.0F && v < static_cast<float>(m.size_z)));
            }
        }
    }
    if (s.num_bscans() < 2) return 0;  // the writer writes volumes only
    std::ostringstream out(std::ios::binary);
    try {
        octshape::io::write_topcon(s, out, 1);
    } catch (const octshape::UsageError&) {
        return 0;  // e.g. a BM at the B-scan's top row leaves no room for RETINA_3 above it
    }
    const octshape::io::Scan r = octshape::io::parse_topcon(out.str(), "fuzz2.fda");
    check(r.num_bscans() == s.num_bscans());
    for (std::size_t b = 0; b < r.bscans.size(); ++b) {
        for (std::size_t k = 0; k < 2; ++k) {
            for (std::size_t a = 0; a < r.bscans[b].seg[k].size(); ++a) {
                check(same(r.bscans[b].seg[k][a], s.bscans[b].seg[k][a]));
            }
        }
    }
    return 0;
}
