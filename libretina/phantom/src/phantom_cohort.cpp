#include "octshape/retina/phantom_cohort.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

#include "octshape/error.h"
#include "octshape/retina/phantom_common.h"
#include "octshape/version.h"

namespace octshape::retina {
namespace {

void require(bool ok, const std::string& field, const std::string& why) {
    if (!ok) throw UsageError("cohort phantom: " + field + " " + why);
}

// 2024-03-14, the phantoms' visit date; subject i is seen 7 i days later.
constexpr double kFirstVisitOle = 45365.0;
constexpr std::uint64_t kFirstExamFiletime = 133548822000000000ULL;
constexpr std::uint64_t kFiletimePerDay = 864000000000ULL;
constexpr std::uint64_t kFiletimePerMinute = 600000000ULL;

std::string numbered(const char* prefix, int i, int width) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%s%0*d", prefix, width, i);
    return buf;
}

}  // namespace

void CohortPhantomParams::validate() const {
    require(subjects >= 2 && subjects <= 9999, "subjects", "must be in 2..9999");
    require(std::isfinite(effect_mm) && std::fabs(effect_mm) <= 0.05, "effect_mm",
            "must be within +-0.05 mm");
    require(std::isfinite(subject_sd_mm) && subject_sd_mm >= 0.0 && subject_sd_mm <= 0.02,
            "subject_sd_mm", "must be in 0..0.02 mm");
    require(std::isfinite(eye_sd_mm) && eye_sd_mm >= 0.0 && eye_sd_mm <= 0.01, "eye_sd_mm",
            "must be in 0..0.01 mm");
    require(std::isfinite(depth_scale_sd) && depth_scale_sd >= 0.0 && depth_scale_sd <= 0.15,
            "depth_scale_sd", "must be in 0..0.15");
    require(retest_subjects >= 0 && retest_subjects <= subjects, "retest_subjects",
            "must be in 0..subjects");
    require(std::isfinite(shift_sd_mm) && shift_sd_mm >= 0.0 && shift_sd_mm <= 0.1, "shift_sd_mm",
            "must be in 0..0.1 mm");
    require(std::isfinite(tilt_max) && tilt_max >= 0.0 && tilt_max <= 0.05, "tilt_max",
            "must be in 0..0.05");
    MaculaPhantomParams m;
    m.num_bscans = num_bscans;
    m.size_x = size_x;
    m.size_z = size_z;
    m.scale_z_mm = scale_z_mm;
    m.noise_um = noise_um;
    m.validate();  // names the sizes and noise fields
}

CohortPlan plan_macula_cohort(const CohortPhantomParams& p) {
    p.validate();
    CohortPlan plan;
    // Independent streams: subject-level, pair-level and scan-level draws do not shift when
    // another count changes.
    phantom::Rng subject_rng(p.seed, 0xC0401ULL);
    phantom::Rng pair_rng(p.seed, 0xC0402ULL);
    phantom::Rng scan_rng(p.seed, 0xC0403ULL);
    const int width = p.subjects >= 1000 ? 4 : 3;
    const int pairs = (p.subjects + 1) / 2;
    // Pit depth scale per pair and eye, shared by the pair's two subjects; clamped to the
    // phantom's allowed range (never reached for SD <= 0.15 in practice: 3.3 SD).
    std::vector<std::array<double, 2>> depth_scale(static_cast<std::size_t>(pairs));
    for (auto& s : depth_scale) {
        const double pair_dev = p.depth_scale_sd * pair_rng.normal();
        for (double& e : s) {
            e = std::clamp(1.0 + pair_dev + 0.25 * p.depth_scale_sd * pair_rng.normal(), 0.5, 1.5);
        }
    }
    nlohmann::ordered_json subjects = nlohmann::ordered_json::array();
    for (int i = 0; i < p.subjects; ++i) {
        const bool is_case = i % 2 == 1;
        const int pair = i / 2;
        const std::string sid = numbered("S", i + 1, width);
        const std::string pid = numbered("FAKE-COHORT-", i + 1, 4);
        const std::string group = is_case ? "case" : "control";
        const double visit_ole = kFirstVisitOle + 7.0 * i;
        const std::string visit = io::ole_date_to_iso_date(visit_ole);
        const double subject_offset =
            (is_case ? p.effect_mm : 0.0) + p.subject_sd_mm * subject_rng.normal();
        nlohmann::ordered_json sj;
        sj["subject_id"] = sid;
        sj["patient_id"] = pid;
        sj["group"] = group;
        sj["pair"] = pair;
        sj["visit_date"] = visit;
        sj["eyes"] = nlohmann::ordered_json::array();
        for (int e = 0; e < 2; ++e) {
            const io::Laterality eye = e == 0 ? io::Laterality::kOD : io::Laterality::kOS;
            const double offset =
                std::clamp(subject_offset + p.eye_sd_mm * subject_rng.normal(), -0.1, 0.1);
            const double scale = depth_scale[static_cast<std::size_t>(pair)][e];
            const int scans = i < p.retest_subjects ? 2 : 1;
            nlohmann::ordered_json ej;
            ej["eye"] = e == 0 ? "OD" : "OS";
            ej["thickness_offset_mm"] = offset;
            ej["pit_depth_scale"] = scale;
            ej["files"] = nlohmann::ordered_json::array();
            for (int k = 1; k <= scans; ++k) {
                CohortScanSpec s;
                s.subject_id = sid;
                s.patient_id = pid;
                s.group = group;
                s.pair = pair;
                s.scan_index = k;
                s.visit_date = visit;
                s.visit_ole = visit_ole;
                s.exam_filetime = kFirstExamFiletime +
                                  static_cast<std::uint64_t>(7 * i) * kFiletimePerDay +
                                  static_cast<std::uint64_t>(10 * (2 * e + k)) * kFiletimePerMinute;
                s.file_name =
                    sid + "_" + ej["eye"].get<std::string>() + "_" + std::to_string(k) + ".vol";
                MaculaPhantomParams& m = s.params;
                m.eye = eye;
                m.num_bscans = p.num_bscans;
                m.size_x = p.size_x;
                m.size_z = p.size_z;
                m.scale_z_mm = p.scale_z_mm;
                m.wall_radius_mm = 0.0;  // flat: the small depth range holds the retina
                m.thickness_offset_mm = offset;
                m.pit_depth_scale = scale;
                m.fovea_dx_mm = std::clamp(p.shift_sd_mm * scan_rng.normal(), -0.3, 0.3);
                m.fovea_dy_mm = std::clamp(p.shift_sd_mm * scan_rng.normal(), -0.3, 0.3);
                m.tilt_x = p.tilt_max * (2.0 * scan_rng.uniform() - 1.0);
                m.tilt_y = p.tilt_max * (2.0 * scan_rng.uniform() - 1.0);
                m.noise_um = p.noise_um;
                m.pixels = p.pixels;
                m.seed = scan_rng.next();
                ej["files"].push_back(s.file_name);
                plan.scans.push_back(std::move(s));
            }
            sj["eyes"].push_back(ej);
        }
        subjects.push_back(sj);
    }

    nlohmann::ordered_json& j = plan.manifest;
    j["kind"] = "octshape phantom cohort manifest";
    // The version only (docs/outputs.md, "Provenance"): the documented command reproduces the
    // file bit for bit from any revision of it.
    j["provenance"] = {{"version", kVersion}};
    j["design"] = {{"subjects", p.subjects},
                   {"seed", p.seed},
                   {"groups", {"control", "case"}},
                   {"reference_group", "control"},
                   {"effect_mm", p.effect_mm},
                   {"subject_sd_mm", p.subject_sd_mm},
                   {"eye_sd_mm", p.eye_sd_mm},
                   {"depth_scale_sd", p.depth_scale_sd},
                   {"retest_subjects", p.retest_subjects},
                   {"shift_sd_mm", p.shift_sd_mm},
                   {"tilt_max", p.tilt_max},
                   {"noise_um", p.noise_um},
                   {"bscans", p.num_bscans},
                   {"ascans", p.size_x},
                   {"depth", p.size_z},
                   {"scale_z_mm", p.scale_z_mm},
                   {"pairing",
                    "subjects 2k (control) and 2k+1 (case) share the pit depth scale "
                    "of each eye"}};
    // The offset adds effect_mm to every thickness of a case eye on average: CFT and rim height
    // move by exactly that, the rim volumes by effect_mm times the area they integrate over.
    j["effects"] = {{"cft_mm", {{"case_minus_control", p.effect_mm}, {"unit", "mm"}}},
                    {"rim_height_mm", {{"case_minus_control", p.effect_mm}, {"unit", "mm"}}},
                    {"rim_volume_mm3", {{"sign", p.effect_mm >= 0.0 ? "+" : "-"}}},
                    {"inner_rim_volume_mm3", {{"sign", p.effect_mm >= 0.0 ? "+" : "-"}}}};
    j["nulls"] = {"pit_depth_mm", "max_pit_slope_deg"};
    j["null_argument"] =
        "A thickness offset leaves pit depth and slopes unchanged (the CuBe curve moves up "
        "rigidly); their true values depend only on the pit depth scale, which matched pairs "
        "(one control, one case) share eye by eye. The true group difference is therefore "
        "exactly 0 and the measured one is measurement error only, small against the "
        "between-pair spread (test-retest ICC ~0.97). pit_flat_diameter_mm has the same exact "
        "null but a measurement error larger than its spread (ICC ~0.2): not asserted.";
    j["retest"] =
        "both eyes of the first retest_subjects subjects: a second scan the same day "
        "with a fresh fovea shift, tilt and noise";
    j["subjects"] = std::move(subjects);
    return plan;
}

void apply_cohort_identity(const CohortScanSpec& spec, io::Scan& scan) {
    io::ScanMeta& m = scan.meta;
    m.ids.patient_id = spec.patient_id;
    m.ids.visit_id = "FAKE-VISIT-" + spec.subject_id;
    m.visit_date_ole = spec.visit_ole;
    m.exam_time_filetime = spec.exam_filetime;
}

}  // namespace octshape::retina
