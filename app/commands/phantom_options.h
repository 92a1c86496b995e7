#pragma once
// Options shared by `phantom onh` and `phantom macula`: the acquisition artefacts
// (docs/phantoms.md, "Acquisition artefacts").

#include <CLI/CLI.hpp>

#include "octshape/retina/phantom_common.h"

namespace octshape::app {

inline void add_acquisition_options(CLI::App* cmd, retina::phantom::AcquisitionArtefacts& a) {
    cmd->add_option("--motion-um", a.motion_sd_um,
                    "Axial eye motion between B-scans: SD of the per-B-scan depth shift (um, "
                    "0-100; a seeded random walk with jumps); the truth is the still eye's")
        ->capture_default_str();
    cmd->add_option("--jitter-um", a.lateral_jitter_um,
                    "Lateral jitter of volume B-scans along their A-scans: SD (um, 0-30)")
        ->capture_default_str();
    cmd->add_flag("--vessel-shadows", a.vessel_shadows,
                  "Vessels in the B-scans: a bright lumen under the ILM, a shadow below it");
    cmd->add_flag("--cleft", a.cleft,
                  "A dark cleft from the ILM into the tissue under one vessel (0.15 mm deep)");
    cmd->add_flag("--segmentation-faults", a.segmentation_faults,
                  "Device-line faults: an ILM spike and a BM gap, away from the disc / fovea");
}

// The speckle grain (docs/phantoms.md, "Speckle"): autocorrelation half-widths in pixels.
inline void add_speckle_grain_options(CLI::App* cmd, double& axial_px, double& lateral_px) {
    cmd->add_option("--speckle-axial-px", axial_px,
                    "Speckle grain along the A-scan: half-width of its autocorrelation (px; 0 = "
                    "independent pixels; real Spectralis 1.9 with 7 looks, docs/phantoms.md "
                    "\"Speckle\")")
        ->capture_default_str();
    cmd->add_option("--speckle-lateral-px", lateral_px,
                    "Speckle grain across A-scans: half-width of its autocorrelation (A-scans; "
                    "0 = independent pixels; real Spectralis 1.6 with 7 looks)")
        ->capture_default_str();
}

}  // namespace octshape::app
