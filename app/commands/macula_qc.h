#pragma once
// QC pictures of one CuBe analysis (`octshape macula --qc DIR`), each titled with the eye, scan
// pattern and size: the thickness map with colour bar (um), 1 mm scale bar, the centre, rim,
// slope and pit-flat disks (a line scan: thickness along the line); the radial profiles with
// their fitted Beziers on axes with values and units; the B-scan through the centre with the
// device ILM and BM and the fitted profile.

#include <string>

#include "octshape/io/scan.h"
#include "octshape/retina/cube.h"

namespace octshape::app {

// Writes DIR/STEM_thickness.png, DIR/STEM_profiles.png and DIR/STEM_bscan.png (atomically).
// `scan` is the analysed scan; its pixels are drawn when loaded. Throws OutputError.
void write_macula_qc(const retina::CubeResult& r, const io::Scan& scan, const std::string& dir,
                     const std::string& stem);

}  // namespace octshape::app
