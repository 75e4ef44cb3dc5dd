// Cost of the CAN protocol's encoders and decoders (the controller encodes one command and decodes three status
// frames per period), against copying the same 16-byte frame (the baseline, measured in the same run).

#include <benchmark/benchmark.h>

#include <cstring>

#include "drivers/can_protocol.h"

namespace {

using namespace visco::drivers::can;

void BM_CopyFrameBaseline(benchmark::State& state) {
  Frame in;
  in.id = 0x201;
  in.dlc = 8;
  Frame out;
  for (auto _ : state) {
    benchmark::DoNotOptimize(&in);
    std::memcpy(&out, &in, sizeof(in));
    benchmark::DoNotOptimize(&out);
  }
}
BENCHMARK(BM_CopyFrameBaseline);

void BM_EncodeCommand(benchmark::State& state) {
  CommandFrame command;
  command.velocity[0] = 0.1234;
  command.velocity[1] = -0.5;
  Frame frame;
  for (auto _ : state) {
    ++command.seq;
    benchmark::DoNotOptimize(EncodeCommand(1, command, frame));
    benchmark::DoNotOptimize(&frame);
  }
}
BENCHMARK(BM_EncodeCommand);

void BM_DecodeCommand(benchmark::State& state) {
  CommandFrame command;
  command.velocity[0] = 0.1234;
  Frame frame;
  EncodeCommand(1, command, frame);
  CommandFrame out;
  std::uint32_t seq = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(&frame);
    benchmark::DoNotOptimize(DecodeCommand(1, frame, out));
    // The session rule the driver applies to every command: the CRC over the nonce and the full counter.
    benchmark::DoNotOptimize(JudgeCommand(frame, command.session, command.seq - 1, 8, seq));
    benchmark::DoNotOptimize(&out);
  }
}
BENCHMARK(BM_DecodeCommand);

void BM_EncodeStatusFrames(benchmark::State& state) {
  StatusFrames status;
  status.position[0] = 1.5;
  status.velocity[1] = 0.2;
  Frame frames[3];
  for (auto _ : state) {
    ++status.seq;
    benchmark::DoNotOptimize(EncodeStatusFrames(1, status, frames));
    benchmark::DoNotOptimize(frames);
  }
}
BENCHMARK(BM_EncodeStatusFrames);

void BM_DecodeStatusFrames(benchmark::State& state) {
  StatusFrames status;
  status.position[0] = 1.5;
  Frame frames[3];
  EncodeStatusFrames(1, status, frames);
  StatusFrames out;
  for (auto _ : state) {
    benchmark::DoNotOptimize(frames);
    benchmark::DoNotOptimize(DecodeStatusFrame(1, frames[0], status.session, status.seq, out));
    benchmark::DoNotOptimize(DecodePositionFrame(1, frames[1], status.session, status.seq, out));
    benchmark::DoNotOptimize(DecodeForceFrame(1, frames[2], status.session, status.seq, out));
  }
}
BENCHMARK(BM_DecodeStatusFrames);

}  // namespace

BENCHMARK_MAIN();
