// The ETDRS part of the per-eye outputs (etdrs.h, docs/outputs.md).

#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "octshape/retina/etdrs.h"
#include "octshape/retina/report_util.h"

namespace octshape::retina {
namespace {

using J = nlohmann::ordered_json;

J num(double v) { return json_number(v); }

J grid_json(const EtdrsGrid& g) {
    J sectors = J::object();
    for (std::size_t k = 0; k < kEtdrsSectorNames.size(); ++k) {
        const EtdrsSector& s = g.sectors[k];
        sectors[std::string(kEtdrsSectorNames[k])] = {{"thickness_mm", num(s.thickness_mm)},
                                                      {"volume_mm3", num(s.volume_mm3)},
                                                      {"coverage", num(s.coverage)}};
    }
    return {{"centre_grid_mm", J::array({g.centre_mm.x(), g.centre_mm.y()})},
            {"centre_thickness_mm", num(g.centre_thickness_mm)},
            {"sectors", sectors},
            {"total_volume_mm3", num(g.total_volume_mm3)},
            {"coverage", num(g.coverage)}};
}

const char* const kAtDevice = "etdrs_at_device_";
const char* const kAtScanCentre = "etdrs_at_scan_centre_";

void add_grid_header(std::vector<std::string>& h, const char* prefix) {
    for (const auto name : kEtdrsSectorNames) h.push_back(prefix + std::string(name) + "_mm");
    h.push_back(prefix + std::string("total_volume_mm3"));
}

void add_grid_values(std::vector<std::string>& v, const std::optional<EtdrsGrid>& g) {
    for (std::size_t k = 0; k < kEtdrsSectorNames.size(); ++k) {
        v.push_back(csv_number(g ? g->sectors[k].thickness_mm : kMissing));
    }
    v.push_back(csv_number(g ? g->total_volume_mm3 : kMissing));
}

}  // namespace

J etdrs_json(const EtdrsReport& r) {
    J j;
    j["options"] = {{"diameters_mm", J::array({r.params.diameters_mm[0], r.params.diameters_mm[1],
                                               r.params.diameters_mm[2]})},
                    {"upper_layer", r.upper_layer},
                    {"lower_layer", r.lower_layer},
                    {"min_coverage", r.params.min_coverage},
                    {"quadrature_step_mm", r.params.step_mm}};
    j["at_fovea_centre"] = r.at_fovea ? grid_json(*r.at_fovea) : J();
    j["at_device_centre"] = r.at_device ? grid_json(*r.at_device) : J();
    j["at_scan_centre"] = r.at_scan_centre ? grid_json(*r.at_scan_centre) : J();
    if (r.device) {
        const DeviceEtdrs& d = *r.device;
        J sectors = J::object();
        for (std::size_t k = 0; k < kEtdrsSectorNames.size(); ++k) {
            J s = {{"thickness_mm", num(d.thickness_mm[k])}, {"volume_mm3", num(d.volume_mm3[k])}};
            if (r.at_device) {
                const double ours = r.at_device->sectors[k].thickness_mm;
                s["ours_minus_device_um"] = num(1e3 * (ours - d.thickness_mm[k]));
            }
            sectors[std::string(kEtdrsSectorNames[k])] = s;
        }
        j["device"] = {{"grid_type", d.type},
                       {"diameters_mm", J::array({d.diameters_mm[0], d.diameters_mm[1],
                                                  d.diameters_mm[2]})},
                       {"centre_grid_mm", J::array({d.centre_mm.x(), d.centre_mm.y()})},
                       {"centre_off_line_mm", r.line_scan ? num(d.centre_off_scan_mm) : J()},
                       {"central_thickness_mm", num(d.central_thickness_mm)},
                       {"ours_at_centre_mm", num(r.ours_at_device_centre_mm)},
                       {"central_difference_um", num(r.central_difference_um)},
                       {"sectors", sectors},
                       {"total_volume_mm3", num(d.total_volume_mm3)}};
    } else {
        j["device"] = J();
    }
    j["qc_flags"] = r.qc_flags;
    j["notes"] = r.notes;
    return j;
}

std::vector<std::string> etdrs_csv_header() {
    std::vector<std::string> h;
    for (const char* prefix : {"etdrs_", kAtDevice}) add_grid_header(h, prefix);
    h.emplace_back("device_central_thickness_mm");
    h.emplace_back("thickness_at_device_centre_mm");
    h.emplace_back("device_central_difference_um");
    // Appended after the device's columns (positions of the earlier ones unchanged).
    add_grid_header(h, kAtScanCentre);
    return h;
}

std::vector<std::string> etdrs_csv_values(const EtdrsReport& r) {
    std::vector<std::string> v;
    for (const auto* g : {&r.at_fovea, &r.at_device}) add_grid_values(v, *g);
    v.push_back(csv_number(r.device ? r.device->central_thickness_mm : kMissing));
    v.push_back(csv_number(r.ours_at_device_centre_mm));
    v.push_back(csv_number(r.central_difference_um));
    add_grid_values(v, r.at_scan_centre);
    return v;
}

}  // namespace octshape::retina
