// Axial motion (a phantom acquisition artefact, docs/phantoms.md) and the macula analysis.

#include <gtest/gtest.h>

#include "octshape/retina/cube.h"
#include "octshape/retina/etdrs.h"
#include "octshape/retina/phantom_macula.h"
#include "vitreous_speckle.h"

namespace octshape::retina {
namespace {

// The macula's thickness is ILM minus BM in each A-scan: axial motion moves both lines of a
// B-scan by the same amount, so every thickness is the still eye's up to the rounding of the
// stored depths. The scan stores them as float32 pixel rows, and the .vol writer writes those
// same float32 values unchanged (no further rounding): at depths below 512 px one float32 ulp
// is 2^-15 px = 3e-5 px = 1.2e-4 um, so ILM - BM moves by at most ~2 ulps = 2.4e-4 um per A-scan,
// and every mean of such differences (CuBe fit, ETDRS sector) by no more. 1e-6 mm (1 nm) leaves
// a factor 4. The motion SDs are the 30 um (typical) and 100 um (the largest).
TEST(MaculaPhantomAcquisition, AxialMotionLeavesTheThicknessParametersUnchanged) {
    MaculaPhantomParams still;
    still.num_bscans = 25;
    still.size_x = 256;
    still.pixels = false;
    const io::Scan still_scan = make_macula_phantom(still).scan;
    const CubeResult a = analyse_macula(still_scan);
    const EtdrsReport ea = etdrs_report(still_scan, a);
    ASSERT_TRUE(ea.at_fovea.has_value());
    for (const double sd_um : {30.0, 100.0}) {
        SCOPED_TRACE(sd_um);
        MaculaPhantomParams moved = still;
        moved.artefacts.motion_sd_um = sd_um;
        moved.artefacts.segmentation_faults = true;  // off the fovea: outside the 2 mm fit
        const io::Scan moved_scan = make_macula_phantom(moved).scan;
        const CubeResult b = analyse_macula(moved_scan);
        EXPECT_NEAR(b.cft_mm, a.cft_mm, 1e-6);
        EXPECT_NEAR(b.rim_height_mm, a.rim_height_mm, 1e-6);
        EXPECT_NEAR(b.pit_depth_mm, a.pit_depth_mm, 1e-6);
        EXPECT_NEAR(b.rim_volume_mm3, a.rim_volume_mm3, 1e-6);
        EXPECT_NEAR(b.pit_volume_mm3, a.pit_volume_mm3, 1e-6);
        EXPECT_NEAR(b.max_pit_slope_deg, a.max_pit_slope_deg, 1e-3);
        // The ETDRS grid about the analysis's fovea: the fovea centre itself is found from the
        // thickness, so it does not move either, and each sector's mean thickness stays.
        const EtdrsReport eb = etdrs_report(moved_scan, b);
        ASSERT_TRUE(eb.at_fovea.has_value());
        EXPECT_NEAR(eb.at_fovea->centre_thickness_mm, ea.at_fovea->centre_thickness_mm, 1e-6);
        for (int s = 0; s < kEtdrsSectors; ++s) {
            EXPECT_NEAR(eb.at_fovea->sectors[s].thickness_mm,
                        ea.at_fovea->sectors[s].thickness_mm, 1e-6)
                << kEtdrsSectorNames[s];
        }
    }
}

// The macula phantom renders the moved eye too: every B-scan of a moving, jittered acquisition
// keeps the still speckle of its vitreous (the bound and its argument:
// OnhPhantomAcquisition.MovedBscansKeepTheStillSpeckle; 96 A-scans, >= 90 vitreous rows).
TEST(MaculaPhantomAcquisition, MovedBscansKeepTheStillSpeckle) {
    MaculaPhantomParams macula;
    macula.size_x = 96;
    macula.num_bscans = 15;
    macula.artefacts.motion_sd_um = 60.0;
    macula.artefacts.lateral_jitter_um = 30.0;
    const io::Scan scan = make_macula_phantom(macula).scan;
    EXPECT_LT(test::worst_vitreous_speckle(scan, 0, macula.speckle.looks), 0.15);
}

}  // namespace
}  // namespace octshape::retina
