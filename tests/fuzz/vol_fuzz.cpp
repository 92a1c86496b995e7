// libFuzzer target for the .vol reader. Each input is read with and without pixels; only
// InputError may come out of read_vol. A successful HSF-OCT-103/104 read with pixels is also
// written back with write_vol and read again, which must give the same scan (a differential
// check of reader and writer on whatever the fuzzer finds acceptable).

#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "fuzz_util.h"
#include "octshape/error.h"
#include "octshape/io/vol.h"

namespace {

using octshape::io::Scan;

using octshape::fuzz::check;
using octshape::fuzz::same;

// What a successful read promises: consistent sizes, missing values NaN, pixels finite.
void check_invariants(const Scan& s, bool pixels) {
    check(s.meta.size_x > 0 && s.meta.size_z > 0 && !s.bscans.empty());
    check(std::isfinite(s.meta.scale_x_mm) && s.meta.scale_x_mm > 0.0);
    check(std::isfinite(s.meta.scale_z_mm) && s.meta.scale_z_mm > 0.0);
    const auto sx = static_cast<std::size_t>(s.meta.size_x);
    const auto sz = static_cast<std::size_t>(s.meta.size_z);
    for (const auto& b : s.bscans) {
        for (const auto& line : b.seg) {
            check(line.size() == sx);
            for (float v : line) check(std::isnan(v) || (std::isfinite(v) && std::fabs(v) < 1e30F));
        }
        check(b.pixels.size() == (pixels ? sx * sz : 0U));
        for (float v : b.pixels) check(std::isfinite(v));
    }
    check(s.slo.size() == (pixels ? static_cast<std::size_t>(s.meta.size_x_slo) *
                                        static_cast<std::size_t>(s.meta.size_y_slo)
                                  : 0U));
}

Scan read(const std::string& bytes, bool pixels) {
    std::istringstream in(bytes, std::ios::binary);
    octshape::io::ReadOptions opt;
    opt.pixels = pixels;
    return octshape::io::read_vol(in, bytes.size(), "fuzz.vol", opt);
}

void check_rewrite(const Scan& s) {
    if (s.meta.version < "HSF-OCT-103") return;  // older B-scan headers may be too short
    std::ostringstream out(std::ios::binary);
    octshape::io::write_vol(s, out);  // must not throw for anything the reader accepted
    const Scan r = read(out.str(), true);
    check(r.meta.size_x == s.meta.size_x && r.meta.size_z == s.meta.size_z);
    check(r.bscans.size() == s.bscans.size() && r.grids.size() == s.grids.size());
    check(r.slo == s.slo && r.meta.ids.patient_id == s.meta.ids.patient_id);
    for (std::size_t i = 0; i < s.bscans.size(); ++i) {
        const auto& p = s.bscans[i];
        const auto& q = r.bscans[i];
        check(p.seg.size() == q.seg.size() && p.pixels.size() == q.pixels.size());
        check(std::bit_cast<std::uint64_t>(p.start_x_mm) ==
              std::bit_cast<std::uint64_t>(q.start_x_mm));
        for (std::size_t k = 0; k < p.seg.size(); ++k) {
            for (std::size_t a = 0; a < p.seg[k].size(); ++a) check(same(p.seg[k][a], q.seg[k][a]));
        }
        for (std::size_t j = 0; j < p.pixels.size(); ++j) check(same(p.pixels[j], q.pixels[j]));
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string bytes(reinterpret_cast<const char*>(data), size);
    for (const bool pixels : {false, true}) {
        try {
            const Scan s = read(bytes, pixels);
            check_invariants(s, pixels);
            if (pixels) check_rewrite(s);
        } catch (const octshape::InputError&) {
            // The expected outcome for damaged input.
        }
    }
    return 0;
}
