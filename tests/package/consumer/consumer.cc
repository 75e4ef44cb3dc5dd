#include <cstdio>

#include "common/latest_value.h"
#include "visco/velocity_command_t.hpp"

int main() {
  visco::LatestValue<double> value;
  value.Publish(1.5);
  double out = 0;
  visco::velocity_command_t command{};
  command.velocity[0] = out;
  const bool ok = value.TryTake(out) && out == 1.5 && command.getEncodedSize() > 0;
  std::printf("consumer: %s\n", ok ? "ok" : "FAILED");
  return ok ? 0 : 1;
}
