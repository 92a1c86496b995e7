#pragma once
// A synthetic macula cohort for the statistics pipeline (docs/phantoms.md, "Cohort phantom"):
// N subjects x 2 eyes in two groups with a known group effect on some CuBe parameters and
// none on others, re-scans of some eyes, obviously fake patient IDs and visit dates.
//
// Design (each choice is what makes the statistical tests decidable):
//  * Subjects alternate between group "control" (even index) and "case" (odd index); subjects
//    2k and 2k+1 form matched pair k.
//  * Thickness offset (MaculaPhantomParams::thickness_offset_mm) per eye = group mean (0 for
//    control, effect_mm for case) + subject deviation (SD subject_sd_mm, shared by both eyes:
//    the inter-eye correlation GEE must handle) + eye deviation (SD eye_sd_mm). It moves CFT,
//    rim height and the rim volumes: the known effect.
//  * Pit depth scale per eye is drawn per matched pair and eye and shared by the pair's two
//    subjects: the true pit depth and maximum slope of a case eye equal those of its control
//    partner exactly, so the group difference of these parameters is measurement noise only
//    (independent shift, tilt and segmentation noise per scan), far smaller than their
//    between-pair spread: these are the asserted nulls.
//  * Re-scans: both eyes of the first retest_subjects subjects get a second scan the same day
//    with a fresh fovea shift, tilt and noise.

#include <array>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "octshape/retina/phantom_macula.h"

namespace octshape::retina {

struct CohortPhantomParams {
    int subjects = 40;  // N in 2..9999
    std::uint64_t seed = 1;
    double effect_mm = 0.025;      // case minus control mean thickness offset
    double subject_sd_mm = 0.012;  // between-subject SD of the thickness offset
    double eye_sd_mm = 0.004;      // between-eye SD within a subject
    double depth_scale_sd = 0.08;  // SD of the pit depth scale between matched pairs
    int retest_subjects = 10;      // subjects whose two eyes are scanned twice (<= subjects)
    double shift_sd_mm = 0.05;     // SD of the true fovea offset from the scan centre per scan
    double tilt_max = 0.005;       // BM tilt per scan uniform in +-tilt_max (mm/mm)
    double noise_um = 2.0;         // segmentation noise SD (ILM and BM)
    int num_bscans = 49;
    int size_x = 256;            // A-scans
    int size_z = 64;             // pixels per A-scan
    double scale_z_mm = 0.0116;  // mm per pixel: 64 px (0.74 mm) hold the ~0.53 mm span
    bool pixels = false;         // B-scan pixels (false: "no data", analysis only, fast)
    // Throws UsageError naming the bad field.
    void validate() const;
};

struct CohortScanSpec {
    std::string file_name;            // e.g. "S001_OD_1.vol"
    std::string subject_id;           // "S001"
    std::string patient_id;           // "FAKE-COHORT-0001" (written into the export)
    std::string group;                // "control" or "case"
    int pair = 0;                     // matched pair index
    int scan_index = 1;               // 1 = first scan of the eye, 2 = re-scan
    std::string visit_date;           // ISO, e.g. "2024-03-14"
    double visit_ole = 0.0;           // the same as an OLE date (days since 1899-12-30)
    std::uint64_t exam_filetime = 0;  // exam time, 100 ns since 1601-01-01 UTC
    MaculaPhantomParams params;       // eye, shape, shift, tilt, noise, seed, sizes
};

struct CohortPlan {
    std::vector<CohortScanSpec> scans;  // subject, eye, scan order
    // The design, which parameters carry an effect and which are asserted nulls, and every
    // scan's true shape variables.
    nlohmann::ordered_json manifest;
};

// The scans of the cohort (deterministic for a seed); nothing is rendered.
[[nodiscard]] CohortPlan plan_macula_cohort(const CohortPhantomParams& p);

// Writes the export's identifiers: patient ID, visit date, exam time (the phantom defaults
// otherwise).
void apply_cohort_identity(const CohortScanSpec& spec, io::Scan& scan);

}  // namespace octshape::retina
