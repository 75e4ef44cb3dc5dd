// Cost of LCM encoding and decoding of a 640x480 grey frame and of a velocity command, against a plain memcpy of
// the same bytes measured in the same run (the baseline: LCM cannot be cheaper than copying).

#include <benchmark/benchmark.h>

#include <cstring>
#include <vector>

#include "visco/image_t.hpp"
#include "visco/velocity_command_t.hpp"

namespace {

visco::image_t MakeFrame(int width, int height) {
  visco::image_t frame;
  frame.width = width;
  frame.height = height;
  frame.row_stride = width;
  frame.pixel_format = visco::image_t::PIXEL_FORMAT_GRAY8;
  frame.data.assign(static_cast<size_t>(width * height), 128);
  frame.size = static_cast<int32_t>(frame.data.size());
  return frame;
}

void BM_MemcpyBaseline(benchmark::State& state) {
  const visco::image_t frame = MakeFrame(640, 480);
  std::vector<uint8_t> out(frame.data.size());
  for (auto _ : state) {
    std::memcpy(out.data(), frame.data.data(), out.size());
    benchmark::DoNotOptimize(out.data());
  }
  state.SetBytesProcessed(state.iterations() * static_cast<int64_t>(out.size()));
}
BENCHMARK(BM_MemcpyBaseline);

void BM_EncodeImage(benchmark::State& state) {
  const visco::image_t frame = MakeFrame(640, 480);
  std::vector<uint8_t> out(static_cast<size_t>(frame.getEncodedSize()));
  for (auto _ : state) {
    benchmark::DoNotOptimize(frame.encode(out.data(), 0, static_cast<int>(out.size())));
  }
  state.SetBytesProcessed(state.iterations() * static_cast<int64_t>(out.size()));
}
BENCHMARK(BM_EncodeImage);

void BM_DecodeImage(benchmark::State& state) {
  const visco::image_t frame = MakeFrame(640, 480);
  std::vector<uint8_t> bytes(static_cast<size_t>(frame.getEncodedSize()));
  frame.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  visco::image_t decoded;
  for (auto _ : state) {
    benchmark::DoNotOptimize(decoded.decode(bytes.data(), 0, static_cast<int>(bytes.size())));
  }
  state.SetBytesProcessed(state.iterations() * static_cast<int64_t>(bytes.size()));
}
BENCHMARK(BM_DecodeImage);

void BM_EncodeVelocityCommand(benchmark::State& state) {
  visco::velocity_command_t command{};
  command.velocity[0] = 0.01;
  uint8_t buffer[256];
  for (auto _ : state) {
    ++command.seq;
    benchmark::DoNotOptimize(command.encode(buffer, 0, sizeof(buffer)));
  }
}
BENCHMARK(BM_EncodeVelocityCommand);

}  // namespace

BENCHMARK_MAIN();
