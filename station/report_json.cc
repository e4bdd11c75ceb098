#include "station/report_json.h"

namespace revolve::station {

nlohmann::json Vec3Json(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

nlohmann::json ModelReportJson(const std::vector<std::string>& files,
                               const reconstruct::MeshStats& stats, std::string_view unit) {
  const std::string u(unit);
  return {{"files", files},
          {"vertices", stats.vertex_count},
          {"triangles", stats.triangle_count},
          {"volume_" + u + "3", stats.volume_mm3},
          {"surface_area_" + u + "2", stats.area_mm2},
          {"bbox_min_" + u, Vec3Json(stats.bbox_min_mm)},
          {"bbox_max_" + u, Vec3Json(stats.bbox_max_mm)},
          {"dimensions_" + u, Vec3Json(stats.bbox_max_mm - stats.bbox_min_mm)},
          {"watertight", stats.closed},
          {"consistently_oriented", stats.oriented}};
}

}  // namespace revolve::station
