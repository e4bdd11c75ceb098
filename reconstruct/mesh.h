// A triangle mesh in the object frame (base/rig.h).
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace revolve::reconstruct {

using Color = Eigen::Matrix<std::uint8_t, 3, 1>;  // RGB

struct Mesh {
  std::vector<Eigen::Vector3f> vertices;
  // Counter-clockwise seen from outside (normals point outward).
  std::vector<Eigen::Vector3i> faces;
  // Empty, or one per vertex.
  std::vector<Color> colors;

  bool HasColors() const { return !colors.empty() && colors.size() == vertices.size(); }
};

}  // namespace revolve::reconstruct
