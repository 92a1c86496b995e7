#pragma once
// QC pictures of one CuBe analysis (`octshape macula --qc DIR`): the thickness map with the
// centre, rim, slope and pit-flat disks; the radial profiles with their fitted Beziers.

#include <string>

#include "octshape/retina/cube.h"

namespace octshape::app {

// Writes DIR/STEM_thickness.png and DIR/STEM_profiles.png (atomically). Throws OutputError.
void write_macula_qc(const retina::CubeResult& r, const std::string& dir, const std::string& stem);

}  // namespace octshape::app
