// libFuzzer target for the Iowa surfaces XML reader. Only InputError may come out of
// parse_iowa_surfaces; a document it accepts must give a scan whose sizes agree with its own
// counts and whose values are finite or NaN, and that scan must go through write_vol and
// read_vol unchanged (a differential check of the surfaces reader against the .vol writer).

#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "fuzz_util.h"
#include "octshape/error.h"
#include "octshape/io/iowa_surfaces.h"
#include "octshape/io/vol.h"

namespace {

using octshape::io::Scan;

using octshape::fuzz::check;
using octshape::fuzz::same;

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view doc(reinterpret_cast<const char*>(data), size);
    octshape::io::IowaSurfaces s;
    try {
        s = octshape::io::parse_iowa_surfaces(doc, "fuzz.xml");
    } catch (const octshape::InputError&) {
        return 0;  // the expected outcome for damaged input
    }
    const auto n = static_cast<std::size_t>(s.size_x) * static_cast<std::size_t>(s.size_z);
    for (const auto& surface : s.surfaces) {
        check(surface.depth_px.size() == n);
        for (float v : surface.depth_px) check(std::isnan(v) || std::fabs(v) <= 1e6F);
    }
    const Scan scan = octshape::io::iowa_scan(s, "fuzz.xml");
    check(scan.num_bscans() == s.size_z && scan.num_lines() == static_cast<int>(s.surfaces.size()));
    std::ostringstream out(std::ios::binary);
    try {
        octshape::io::write_vol(scan, out);
    } catch (const octshape::UsageError&) {
        // The writer refuses what a .vol cannot hold (e.g. a pixel row beyond its float range
        // never occurs here, but sizes beyond the writer's limits may): not a reader bug.
        return 0;
    }
    const std::string bytes = out.str();
    std::istringstream in(bytes, std::ios::binary);
    const Scan r = octshape::io::read_vol(in, bytes.size(), "fuzz.vol", {});
    check(r.bscans.size() == scan.bscans.size());
    for (std::size_t b = 0; b < r.bscans.size(); ++b) {
        check(r.bscans[b].seg.size() == scan.bscans[b].seg.size());
        for (std::size_t k = 0; k < r.bscans[b].seg.size(); ++k) {
            for (std::size_t a = 0; a < r.bscans[b].seg[k].size(); ++a) {
                check(same(r.bscans[b].seg[k][a], scan.bscans[b].seg[k][a]));
            }
        }
    }
    return 0;
}
