#pragma once
// `visco critical SCENE [--kernel] [--slices] [--svg FILE] [--threads N] [--method kinetic|baseline] [--out FILE]`
// (docs/formats.md); its picture is the area profile (planning/area_profile.h).

namespace CLI {
class App;
}

namespace visco::planning {

/// Registers `visco critical` on `app`.
void RegisterCriticalCommand(CLI::App& app);

}  // namespace visco::planning
