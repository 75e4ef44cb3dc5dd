// Publishes one filled-in message of every visco type on channel "SPYTEST_<type>", `--repeat` times at 10 Hz,
// on the LCM URL given as the first argument. Used by the lcm-spy test.

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <lcm/lcm-cpp.hpp>
#include <string>
#include <thread>

#include "tests/lcmtypes/fill_messages.h"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: lcmtypes_publish_all LCM_URL [REPEAT]\n");
    return 2;
  }
  const int repeat = argc > 2 ? std::atoi(argv[2]) : 20;
  lcm::LCM bus(argv[1]);
  if (!bus.good()) {
    std::fprintf(stderr, "lcmtypes_publish_all: cannot open LCM at %s\n", argv[1]);
    return 1;
  }
  for (int i = 0; i < repeat; ++i) {
#define VISCO_PUBLISH(type)                                     \
  {                                                             \
    visco::type message;                                        \
    visco::testing::Fill(message);                              \
    if (bus.publish("SPYTEST_" #type, &message) != 0) return 1; \
  }
    VISCO_FOR_EACH_LCM_TYPE(VISCO_PUBLISH)
#undef VISCO_PUBLISH
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  std::printf("%d\n", VISCO_LCM_TYPE_COUNT);
  return 0;
}
