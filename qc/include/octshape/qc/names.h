#pragma once
// The names of the QC pictures of one eye, in one place: the picture writers (macula.h,
// onh.h), the cohort's resume (an eye is done with --qc only when its pictures exist) and
// the gallery (which picture belongs to which eye and what it shows) all use these.
// DIR/STEM_KIND.png; STEM is the -o stem of a single-eye command or the eye key in a cohort,
// never the input's name (docs/outputs.md).

#include <string>
#include <vector>

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

// The kinds a scan type ("macula", "onh") gets, in the order they are drawn.
inline std::vector<std::string> kinds(const std::string& scan_type) {
    if (scan_type == "onh") return {kind::kEnface, kind::kBscans, kind::kMrw};
    return {kind::kThickness, kind::kProfiles, kind::kBscan};
}

// "STEM_KIND.png".
inline std::string picture_name(const std::string& stem, const std::string& kind) {
    return stem + "_" + kind + ".png";
}

// Every picture name of one eye of `scan_type`.
inline std::vector<std::string> picture_names(const std::string& stem,
                                              const std::string& scan_type) {
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
