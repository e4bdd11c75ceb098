// The simulated rig's shared plate: the mock turntable writes its angle, the synthetic camera
// reads it to render the object where the plate is now. `station` creates one and hands it to
// both, so `turntable` and `capture` never know each other.
#pragma once

#include <atomic>

namespace revolve {

struct SimulatedPlate {
  std::atomic<double> angle_deg{0.0};
  std::atomic<bool> moving{false};
};

}  // namespace revolve
