#include "commands/macula_eye.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <sstream>

#include "commands/eye_output.h"
#include "octshape/qc/macula.h"
#include "commands/provenance.h"
#include "octshape/error.h"
#include "octshape/io/scan_reader.h"
#include "octshape/retina/cube_report.h"
#include "octshape/retina/scan_summary.h"
#include "octshape/retina/scan_type.h"

namespace octshape::app {

std::string macula_options_text(const MaculaEyeOptions& o) {
    // Every field of CubeParams, the defaults the command line does not expose included (the
    // local-fit threshold, the fit's rounds and tolerance, the QC threshold), and the
    // classifier's, which decides the analysis in a cohort: the fingerprint's parameter text.
    const auto& p = o.params;
    const retina::ScanTypeParams classifier;
    std::ostringstream s;
    s.precision(17);
    s << "macula half_lines=" << p.num_half_lines << " radius_mm=" << p.radius_mm
      << " spacing_mm=" << p.sample_spacing_mm << " tau_um=" << o.tau_um
      << " inner_radius_mm=" << p.inner_radius_mm << " search_radius_mm=" << p.search_radius_mm
      << " tie_tolerance_mm=" << p.tie_tolerance_mm
      << " centre_smoothing_mm=" << p.centre_smoothing_mm
      << " centre_fit_radius_mm=" << p.centre_fit_radius_mm << " max_rounds=" << p.max_rounds
      << " energy_tolerance=" << p.energy_tolerance << " rim_point=" << o.rim_point
      << " rmse_warning_um=" << p.rmse_warning_um
      << " local_fit_min_noise_um=" << p.local_fit_min_noise_um
      << " lateral_registration=" << (p.lateral_registration.enabled ? "true" : "false")
      << " lateral_registration_wavelength_mm=" << p.lateral_registration.smooth_wavelength_mm
      << " lateral_registration_wavelength_bscans=" << p.lateral_registration.smooth_wavelength_bscans
      << " lateral_registration_line_smoothing_ascans="
      << p.lateral_registration.line_smoothing_ascans
      << " lateral_registration_whole_ascans="
      << (p.lateral_registration.whole_ascans ? "true" : "false")
      << " lateral_registration_step_ascans=" << p.lateral_registration.step_tolerance_ascans
      << " centre_mm=";
    if (p.centre_mm) {
      s << p.centre_mm->x() << "," << p.centre_mm->y();
    } else {
      s << "search";
    }
    s << " classifier_min_gap_mm=" << classifier.min_gap_mm
      << " classifier_min_bscans=" << classifier.min_bscans;
    // The ETDRS options (a new one, e.g. for the sectors at the scan centre, is added here).
    const auto& e = o.etdrs;
    s << " etdrs(diameters_mm=" << e.diameters_mm[0] << "," << e.diameters_mm[1] << ","
      << e.diameters_mm[2] << " step_mm=" << e.step_mm << " min_coverage=" << e.min_coverage
      << " layers=" << o.etdrs_layers << ") " << segmentation_options_text(o.segmentation);
    return s.str();
}

nlohmann::ordered_json macula_options(const MaculaEyeOptions& o) {
    return options_from_text(macula_options_text(o));
}

retina::CubeParams effective_params(const MaculaEyeOptions& o) {
    retina::CubeParams p = o.params;
    p.tau_mm = o.tau_um * 1e-3;
    p.rim_point = retina::parse_rim_point(o.rim_point);
    p.validate();
    return p;
}

void add_macula_analysis_options(CLI::App* cmd, MaculaEyeOptions& o, bool lateral_flag) {
    auto& p = o.params;
    cmd->add_option("--half-lines", p.num_half_lines, "Number of radial half-lines n (even)")
        ->capture_default_str();
    cmd->add_option("--radius-mm", p.radius_mm, "Length R of each half-line (mm)")
        ->capture_default_str();
    cmd->add_option("--spacing-mm", p.sample_spacing_mm,
                    "Radial sample spacing (mm); 0 = the scan's ScaleX")
        ->capture_default_str();
    cmd->add_option("--tau-um", o.tau_um, "Pit-flat threshold above CFT (um)")
        ->capture_default_str();
    cmd->add_option("--inner-radius-mm", p.inner_radius_mm,
                    "Radius r_u of the inner rim volume (mm)")
        ->capture_default_str();
    cmd->add_option("--search-radius-mm", p.search_radius_mm,
                    "Centre search radius around the device fovea centre (mm)")
        ->capture_default_str();
    cmd->add_option("--rim", o.rim_point,
                    "Rim point of each half-line: crest (fitted among the samples within 3 noise "
                    "SDs of the maximum) or maximum (the maximum sample, as in the thesis)")
        ->check(CLI::IsMember({"crest", "maximum"}))
        ->capture_default_str();
    if (lateral_flag) {
        cmd->add_flag_callback(
            "--no-lateral-registration", [&p] { p.lateral_registration.enabled = false; },
            "Do not remove the lateral shifts of a volume's B-scans (estimated from the ILM and "
            "BM lines and reported either way; docs/algorithms/cube.md)");
    }
    cmd->add_option("--etdrs-layers", o.etdrs_layers,
                    "ETDRS sector thickness between these two lines, UPPER,LOWER (names as "
                    "`octshape info` lists them, e.g. ILM,RNFL)")
        ->capture_default_str();
    cmd->add_option("--etdrs-min-coverage", o.etdrs.min_coverage,
                    "Measured fraction of an ETDRS sector's area needed to report it")
        ->capture_default_str();
}

namespace {

// "UPPER,LOWER" -> the two names; UsageError otherwise.
std::pair<std::string, std::string> etdrs_layer_names(const std::string& text) {
    const auto comma = text.find(',');
    if (comma == std::string::npos || comma == 0 || comma + 1 >= text.size() ||
        text.find(',', comma + 1) != std::string::npos) {
        throw UsageError("--etdrs-layers must be two line names separated by a comma (e.g. "
                         "ILM,BM), not '" + text + "'");
    }
    return {text.substr(0, comma), text.substr(comma + 1)};
}

}  // namespace

MaculaEye analyse_macula_eye(const std::string& file,
                             MaculaEyeOptions options,
                             const SubjectSource& subjects) {
    const FileFacts facts = file_facts(file);  // before reading: a missing file says so
    // The QC B-scan shows the pixels: read them with the rest when pictures are asked for.
    io::ReadOptions read_options;
    read_options.pixels = !options.qc_dir.empty();
    read_options.iowa_bm = segmentation_bm(options.segmentation);
    Provenance read;
    io::HashedScan input = io::read_scan_hashed(file, read_options);
    const nlohmann::ordered_json segmentation =
        apply_segmentation_file(input.scan, options.segmentation, options.record_paths);
    read.mark("read_hash");
    MaculaEye r = analyse_macula_eye(file, facts, input, std::move(options), subjects);
    if (!segmentation.is_null()) r.json["input"]["segmentation"] = segmentation;
    add_segmentation_input(r.json["provenance"]["inputs"], segmentation);
    prepend_stages(r.json["provenance"], read);  // the reading came first
    return r;
}

MaculaEye analyse_macula_eye(const std::string& file,
                             const FileFacts& facts,
                             const io::HashedScan& input,
                             MaculaEyeOptions o,
                             const SubjectSource& subjects) {
    Provenance prov("macula");
    const std::string& sha = input.sha256;
    o.params = effective_params(o);
    if (o.check_scan_type) {
        const auto type = retina::classify_scan(input.scan);
        if (type.type == retina::ScanType::kOnh) {
            throw AnalysisError(file + ": an optic nerve head scan, not a macula scan (" +
                                type.reason + "); --no-type-check analyses it anyway");
        }
    }
    const auto [upper, lower] = etdrs_layer_names(o.etdrs_layers);
    // Lateral registration of a volume's B-scans before the thickness map (docs/algorithms/
    // cube.md, step 1): the scan is copied only when something moves; a still scan is analysed
    // as read.
    const retina::LateralRegistration lateral = with_file_named(
        file, [&] { return retina::estimate_lateral_motion(input.scan, o.params.lateral_registration); });
    io::Scan registered;
    if (lateral.applied) {
        registered = input.scan;
        retina::apply_lateral_registration(registered, lateral);
    }
    const io::Scan& scan = lateral.applied ? registered : input.scan;
    prov.mark("lateral_registration");
    retina::CubeResult r =
        with_file_named(file, [&] { return retina::analyse_macula(scan, o.params); });
    r.lateral_registration = lateral;
    // A volume whose shifts cannot be estimated at all (B-scans too far apart: the 19- and
    // 25-line protocols) is a note, not a QC flag, in the macula: jitter moves its parameters
    // by about 1 % (docs/algorithms/cube.md, step 1), and a flag on every sparse volume would
    // hide the flags that need a look. Large motion and too little slope stay flags.
    std::vector<std::string> lateral_flags;
    for (const std::string& f : lateral.qc_flags) {
        if (f.rfind("lateral motion not estimated", 0) == 0) {
            r.notes.insert(r.notes.begin(), f);
        } else {
            lateral_flags.push_back(f);
        }
    }
    r.qc_flags.insert(r.qc_flags.begin(), lateral_flags.begin(), lateral_flags.end());
    r.notes.insert(r.notes.begin(), lateral.notes.begin(), lateral.notes.end());
    const retina::EtdrsReport etdrs = with_file_named(
        file, [&] { return retina::etdrs_report(scan, r, o.etdrs, upper, lower); });
    // The device comparison's flags are the eye's: in the JSON's and the CSV's qc_flags.
    r.qc_flags.insert(r.qc_flags.end(), etdrs.qc_flags.begin(), etdrs.qc_flags.end());
    prov.mark("analysis");
    const std::string who = log_name(file);
    for (const auto& f : r.qc_flags) spdlog::warn("{}: QC: {}", who, f);
    for (const auto& n : r.notes) spdlog::info("{}: {}", who, n);

    MaculaEye out;
    auto& j = out.json;
    j = eye_json_preamble("macula", file, sha, scan, o.record_paths);
    const auto cube = retina::cube_json(r, o.params, macula_options(o));
    for (const auto& [k, v] : cube.items()) j[k] = v;
    j["etdrs"] = retina::etdrs_json(etdrs);
    const std::string eye(io::to_string(scan.meta.laterality));

    const auto cols = eyes_type_header(retina::ScanType::kMacula);  // the CuBe columns, then the ETDRS ones
    auto vals = retina::cube_csv_values(r);
    for (const auto& v : retina::etdrs_csv_values(etdrs)) vals.push_back(v);
    out.csv_header = eye_csv_header(o.record_paths);
    out.csv_row = eye_csv_values(file, sha, scan, o.record_paths);
    out.csv_header.insert(out.csv_header.end(), cols.begin(), cols.end());
    out.csv_row.insert(out.csv_row.end(), vals.begin(), vals.end());
    const std::string options_text =
        macula_options_text(o) + " subjects=" + subjects.fingerprint();
    attach_cohort_record(j, cols, vals, facts, options_text, retina::ScanType::kMacula, scan,
                         subjects, file);
    prov.add_input(sha, o.record_paths ? file : std::string());
    prov.set_options(eye_provenance_options(options_text, o.qc_dir, o.record_paths));

    if (!o.qc_dir.empty()) {
        const std::string stem = o.qc_stem.empty() ? std::string("eye") : o.qc_stem;
        // The caller read the pixels with the rest (MaculaEyeOptions::qc_dir): the file is
        // read once.
        qc::write_macula_qc(r, scan, o.qc_dir, stem);
        prov.mark("qc_pictures");
    }
    j["provenance"] = prov.json();
    spdlog::info("{}: {} eye, CFT {:.4f} mm, rim height {:.4f} mm, RMSE {:.2f} um", who, eye,
                 r.cft_mm, r.rim_height_mm, r.rmse_um);
    return out;
}

}  // namespace octshape::app
