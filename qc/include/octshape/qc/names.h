#pragma once
// The names of the QC pictures of one eye, in one place: the picture writers (macula.h,
// onh.h), the cohort's resume (an eye is done with --qc only when its pictures exist) and
// the gallery (which picture belongs to which eye and what it shows) all use these.
// DIR/STEM_KIND.png; STEM is the -o stem of a single-eye command or the eye key in a cohort,
// never the input's name (docs/outputs.md).

#include <string>
#include <vector>

#include "octshape/retina/scan_type.h"

namespace octshape::qc {

namespace kind {
// Macula: the thickness map (a profile for a line scan), the half-line profiles, the B-scan.
inline constexpr const char* kThickness = "thickness";
inline constexpr const char* kProfiles = "profiles";
inline constexpr const char* kBscan = "bscan";
// ONH: the en-face height map, three B-scans through the disc, MRW against the angle.
inline constexpr const char* kEnface = "enface";
inline constexpr const char* kBscans = "bscans";
inline constexpr const char* kMrw = "mrw";
}  // namespace kind

// The kinds a scan type gets, in the order they are drawn (kUnsupported: none).
inline std::vector<std::string> kinds(retina::ScanType scan_type) {
    switch (scan_type) {
        case retina::ScanType::kMacula:
            return {kind::kThickness, kind::kProfiles, kind::kBscan};
        case retina::ScanType::kOnh:
            return {kind::kEnface, kind::kBscans, kind::kMrw};
        case retina::ScanType::kUnsupported:
            break;
    }
    return {};
}

// What a picture of `kind` shows, as the commands' --qc help says it ("" for an unknown kind).
inline std::string what_it_shows(const std::string& kind) {
    if (kind == kind::kThickness) {
        return "thickness map in the fundus frame, superior up, N S T I marked: centre, "
               "rim/slope/pit-flat disks; a radial scan: along each line; a line scan: along "
               "the line";
    }
    if (kind == kind::kProfiles) return "half-lines with their fitted Beziers";
    if (kind == kind::kBscan) return "the B-scan through the centre, device lines, fitted profile";
    if (kind == kind::kEnface) {
        return "height map in the fundus frame, superior up, N S T I marked: BMO points, "
               "ellipse, disc";
    }
    if (kind == kind::kBscans) {
        return "B-scans through the disc, ILM used vs device ILM, MRW vectors; a radial scan: "
               "every B-scan, in-plane MRW";
    }
    if (kind == kind::kMrw) return "MRW against the anatomical angle";
    return "";
}

// The pictures of `scan_type` for a command's --qc help: "STEM_thickness.png (what it shows),
// STEM_profiles.png (...) and STEM_bscan.png (...)".
inline std::string help_list(retina::ScanType scan_type) {
    const std::vector<std::string> k = kinds(scan_type);
    std::string s;
    for (std::size_t i = 0; i < k.size(); ++i) {
        if (i > 0) s += i + 1 == k.size() ? " and " : ", ";
        s += "STEM_" + k[i] + ".png (" + what_it_shows(k[i]) + ")";
    }
    return s;
}

// "STEM_KIND.png".
inline std::string picture_name(const std::string& stem, const std::string& kind) {
    return stem + "_" + kind + ".png";
}

// Every picture name of one eye of `scan_type`.
inline std::vector<std::string> picture_names(const std::string& stem,
                                              retina::ScanType scan_type) {
    std::vector<std::string> names;
    for (const auto& k : kinds(scan_type)) names.push_back(picture_name(stem, k));
    return names;
}

// KIND when `file` is a picture name of `stem` ("STEM_KIND.png" with a non-empty KIND), else "".
inline std::string picture_kind(const std::string& stem, const std::string& file) {
    const std::string prefix = stem + "_";
    const std::string suffix = ".png";
    if (file.size() <= prefix.size() + suffix.size() || !file.starts_with(prefix) ||
        !file.ends_with(suffix)) {
        return "";
    }
    return file.substr(prefix.size(), file.size() - prefix.size() - suffix.size());
}

}  // namespace octshape::qc
