#include "planning/threads.h"

namespace visco::planning {

int MachineThreads() { return static_cast<int>(std::max(1u, std::thread::hardware_concurrency())); }

}  // namespace visco::planning
