// Axial motion (a phantom acquisition artefact, docs/phantoms.md) and the macula analysis.

#include <gtest/gtest.h>

#include "octshape/retina/cube.h"
#include "octshape/retina/phantom_macula.h"

namespace octshape::retina {
namespace {

// The macula's thickness is ILM minus BM in each A-scan: axial motion moves both lines of a
// B-scan together, so every CuBe parameter is that of the still eye up to the float32 rounding
// of the shifted depths (~3e-5 px = 1e-4 um). 1e-6 mm (1 nm) leaves a factor 10.
TEST(MaculaPhantomAcquisition, AxialMotionLeavesTheThicknessParametersUnchanged) {
    MaculaPhantomParams still;
    still.num_bscans = 25;
    still.size_x = 256;
    still.pixels = false;
    MaculaPhantomParams moved = still;
    moved.artefacts.motion_sd_um = 60.0;
    moved.artefacts.segmentation_faults = true;  // off the fovea: outside the 2 mm fit
    const CubeResult a = analyse_macula(make_macula_phantom(still).scan);
    const CubeResult b = analyse_macula(make_macula_phantom(moved).scan);
    EXPECT_NEAR(b.cft_mm, a.cft_mm, 1e-6);
    EXPECT_NEAR(b.rim_height_mm, a.rim_height_mm, 1e-6);
    EXPECT_NEAR(b.pit_depth_mm, a.pit_depth_mm, 1e-6);
    EXPECT_NEAR(b.rim_volume_mm3, a.rim_volume_mm3, 1e-6);
    EXPECT_NEAR(b.pit_volume_mm3, a.pit_volume_mm3, 1e-6);
    EXPECT_NEAR(b.max_pit_slope_deg, a.max_pit_slope_deg, 1e-3);
}

}  // namespace
}  // namespace octshape::retina
