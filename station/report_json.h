// Pieces of report.json shared by a scan (ScanSession) and its rebuilds (revolve reconstruct).
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "reconstruct/metrics/metrics.h"

namespace revolve::station {

// [x, y, z].
nlohmann::json Vec3Json(const Eigen::Vector3d& v);

// report.json's "model": the files and the mesh's figures, lengths named by `unit` ("mm" with a
// metric geometry, "px" in the thesis's mode: volume_mm3, bbox_min_px, ...).
nlohmann::json ModelReportJson(const std::vector<std::string>& files,
                               const reconstruct::MeshStats& stats, std::string_view unit);

}  // namespace revolve::station
