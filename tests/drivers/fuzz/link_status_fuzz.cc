// Property fuzzer of the SocketCAN link's status-triple assembly: arbitrary bytes become the frames a
// controller's link receives (drivers/README.md, "Sessions"): the driver's status triples (status, position, force
// with one counter, each with the CRC over the session nonce and the counter), lost frames, counters jumping ahead,
// replays of earlier triples whole or in part, triples of other sessions, single-bit corruptions, frames out of
// order, session announcements (new ones and replayed old ones), heartbeats and boot-ups. The link runs its real code
// (MakeCanRobotLink over ports in memory). After every frame:
// - a status the link delivers is exactly the decode, under the link's session and the delivered counter, of the
//   last status frame it read, the first position frame after it and the force frame just read;
// - its counter is 1..kStatusWindow ahead of the last one delivered in the same session, so a triple is never
//   delivered twice: a replay never refreshes the view of the driver;
// - a fresh triple of the announced session, read whole and in order, 1..kStatusWindow ahead, is delivered (the
//   check cannot pass by delivering nothing);
// - a triple that is not genuine (another session's, or corrupted in more than one bit) is accepted only where the
//   8-bit CRCs of all three frames collide, counted and reported (about 2^-23 per attempt).
// LINK_FUZZ_DEBUG=1 prints every non-genuine triple accepted, with the operation that fed it.
// Built as a seeded random driver for every build (VISCO_FUZZ_STANDALONE, `drivers.link_status_fuzz_seeded`); the
// same LLVMFuzzerTestOneInput can be linked with libFuzzer.

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <random>
#include <vector>

#include "drivers/can_protocol.h"
#include "drivers/robot_link.h"
#include "drivers/socketcan.h"
#include "tests/drivers/memory_port.h"

namespace {

using namespace visco::drivers;

#define Require(condition) RequireAt((condition), #condition, __LINE__)
void RequireAt(bool condition, const char* what, int line) {
  if (!condition) {
    std::fprintf(stderr, "link_status_fuzz: property failed (line %d): %s\n", line, what);
    std::abort();
  }
}

constexpr int kNode = 1;

using visco::drivers::testing::MemoryPort;  // the link's receive side: frames the harness queues, one at a time

struct Triple {
  std::uint32_t session = 0;
  std::uint32_t seq = 0;
  can::Frame frames[3];
};

bool SameFrame(const can::Frame& a, const can::Frame& b) {
  return a.id == b.id && a.dlc == b.dlc && std::memcmp(a.data, b.data, 8) == 0;
}

struct Exercised {
  std::uint64_t frames = 0;
  std::uint64_t delivered = 0;
  std::uint64_t fresh_whole = 0;  // fresh triples read whole and in order (each one must be delivered)
  std::uint64_t replays = 0;
  std::uint64_t foreign = 0;
  std::uint64_t corrupted = 0;
  std::uint64_t announcements = 0;
  std::uint64_t collisions = 0;  // non-genuine triples accepted because all three CRCs collided
};
Exercised g_exercised;

class Harness {
 public:
  Harness() {
    auto rx = std::make_unique<MemoryPort>();
    port_ = rx.get();
    RobotLinkConfig config;
    config.node_id = kNode;
    config.heartbeat_timeout_us = 1'000'000'000;
    link_ = MakeCanRobotLink(config, std::move(rx), std::make_unique<MemoryPort>());
  }

  // The driver's side.
  void NewSession(std::uint32_t nonce, std::uint32_t seq_start) {
    if (nonce == 0) nonce = 1;
    driver_session_ = nonce;
    driver_seq_ = seq_start;
    Announce(driver_session_, driver_seq_);
    sessions_.push_back({driver_session_, driver_seq_});
  }
  void Announce(std::uint32_t nonce, std::uint32_t seq) {
    can::SessionFrame s;
    s.session = nonce;
    s.status_epoch = seq >> 8;
    can::Frame f;
    Require(can::EncodeSession(kNode, s, f) == can::EncodeStatus::kOk);
    ++g_exercised.announcements;
    Feed(f);
  }
  Triple MakeTriple(std::uint32_t session, std::uint32_t seq, std::uint8_t seed) {
    can::StatusFrames s;
    s.seq = seq;
    s.session = session;
    s.command_seq = 0;  // this link sends nothing: a status with accepted commands would be another controller's
    s.velocity[0] = (seed % 7) * 0.01;
    s.velocity[1] = -(seed % 5) * 0.01;
    s.state = static_cast<RobotState>(seed % 5);
    s.contact = (seed & 1) != 0;
    s.position[0] = seq * 1e-4;
    s.position[1] = -(seed * 1e-3);
    s.contact_force[0] = (seed % 3) * 0.5;
    s.fault_bits = static_cast<std::uint16_t>(seed & 0x3F);
    Triple t;
    t.session = session;
    t.seq = seq;
    Require(can::EncodeStatusFrames(kNode, s, t.frames) == can::EncodeStatus::kOk);
    return t;
  }
  // The next status of the driver's current session, `skip` counters after the last one (lost statuses).
  Triple NextTriple(std::uint32_t skip, std::uint8_t seed) {
    driver_seq_ += 1 + skip;
    Triple t = MakeTriple(driver_session_, driver_seq_, seed);
    history_.push_back(t);
    if (history_.size() > 4096) history_.erase(history_.begin(), history_.begin() + 2048);
    return t;
  }

  // Feeds one frame to the link and checks what it delivers.
  void Feed(const can::Frame& frame) {
    ++g_exercised.frames;
    now_us_ += 100;
    port_->queue.push_back(ReceivedFrame{frame, now_us_});
    const std::uint32_t base = frame.id & ~0x7Fu;
    const bool ours = (frame.id & 0x7F) == kNode;
    // The link takes the first position frame after a status frame (a later one, e.g. replayed, is ignored).
    if (ours && base == can::kStatusBase) {
      last_status_ = frame;
      have_position_ = false;
    }
    if (ours && base == can::kPositionBase && !have_position_) {
      last_position_ = frame;
      have_position_ = true;
    }
    // The session as the link must know it after this frame (drivers/README.md, "Sessions"): an announcement of
    // another nonce is adopted and the counter is reconstructed from its epoch until the first status; an
    // announcement of the current one only refreshes the epoch before that; a boot-up forgets the session.
    can::SessionFrame announced;
    NmtState nmt = NmtState::kOperational;
    if (ours && can::DecodeSession(kNode, frame, announced) == can::DecodeStatus::kOk) {
      if (!have_session_ || announced.session != known_session_) {
        known_session_ = announced.session;
        have_session_ = true;
        synced_ = false;
        last_delivered_ = 0;
        announced_epoch_ = announced.status_epoch;
      } else if (!synced_) {
        announced_epoch_ = announced.status_epoch;
      }
    } else if (ours && can::DecodeHeartbeat(kNode, frame, nmt) == can::DecodeStatus::kOk && nmt == NmtState::kBootUp) {
      have_session_ = false;
      synced_ = false;
    }
    link_->Poll(now_us_);
    RobotStatus status;
    const bool delivered = link_->TakeStatus(status) == LinkResult::kOk;
    Require(!have_session_ || link_->session() == known_session_);
    if (!delivered) return;
    Require(have_session_);
    ++g_exercised.delivered;
    Require(ours && base == can::kForceBase);
    Require(status.session == known_session_);
    if (synced_) {
      Require(status.seq - last_delivered_ >= 1 && status.seq - last_delivered_ <= kStatusWindow);
    }
    // Exactly the decode of the frames read, under the link's session and the delivered counter.
    can::StatusFrames s, p, f;
    Require(can::DecodeStatusFrame(kNode, last_status_, known_session_, status.seq, s) == can::DecodeStatus::kOk);
    Require(can::DecodePositionFrame(kNode, last_position_, known_session_, status.seq, p) == can::DecodeStatus::kOk);
    Require(can::DecodeForceFrame(kNode, frame, known_session_, status.seq, f) == can::DecodeStatus::kOk);
    Require(status.velocity[0] == s.velocity[0] && status.velocity[1] == s.velocity[1]);
    Require(status.state == s.state && status.contact == s.contact);
    Require(status.position[0] == p.position[0] && status.position[1] == p.position[1]);
    Require(status.contact_force[0] == f.contact_force[0] && status.contact_force[1] == f.contact_force[1]);
    Require(status.fault_bits == f.fault_bits);
    // Genuine: the three frames of one triple the driver made in that session with that counter.
    bool genuine = false;
    for (const Triple& t : history_) {
      if (t.session == known_session_ && t.seq == status.seq && SameFrame(t.frames[0], last_status_) &&
          SameFrame(t.frames[1], last_position_) && SameFrame(t.frames[2], frame)) {
        genuine = true;
        break;
      }
    }
    if (!genuine) {
      ++g_exercised.collisions;
      if (std::getenv("LINK_FUZZ_DEBUG") != nullptr) {
        std::fprintf(stderr, "non-genuine: seq %u session %08x driver %08x/%u op %d\n", status.seq, known_session_,
                     driver_session_, driver_seq_, last_op_);
      }
    }
    last_delivered_ = status.seq;
    synced_ = true;
    delivered_now_ = true;
  }

  // Feeds a triple whole and in order; `fresh`: it must be delivered.
  void FeedWhole(const Triple& t, bool must_deliver) {
    delivered_now_ = false;
    for (const can::Frame& f : t.frames) Feed(f);
    if (must_deliver) {
      ++g_exercised.fresh_whole;
      Require(delivered_now_);
    }
  }

  // True if the fresh triple `t` of the driver's session must be delivered when read whole.
  bool MustDeliver(const Triple& t) const {
    if (!have_session_ || known_session_ != t.session) return false;
    if (synced_) return t.seq - last_delivered_ >= 1 && t.seq - last_delivered_ <= kStatusWindow;
    // Before the first status of a session the link reconstructs the counter from the announced epoch, trying the
    // epoch first and then the next one (a wrap since the announcement). When the counter is in the next epoch, the
    // first try can pass the 8-bit CRC by chance (1 in 256): that status is then lost, as on a real bus.
    const std::uint32_t first = (announced_epoch_ << 8) | (t.seq & 0xFF);
    if (t.seq == first) return true;
    if ((t.seq >> 8) != announced_epoch_ + 1) return false;
    can::StatusFrames s;
    return can::DecodeStatusFrame(kNode, t.frames[0], t.session, first, s) != can::DecodeStatus::kOk;
  }

  MemoryPort* port_ = nullptr;
  std::unique_ptr<RobotLink> link_;
  std::uint32_t driver_session_ = 0;
  std::uint32_t driver_seq_ = 0;
  std::uint32_t announced_epoch_ = 0;
  bool have_session_ = false;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> sessions_;  // every session made: nonce, first counter
  std::vector<Triple> history_;
  std::int64_t now_us_ = 0;
  can::Frame last_status_, last_position_;
  bool have_position_ = false;
  std::uint32_t known_session_ = 0;
  std::uint32_t last_delivered_ = 0;
  bool synced_ = false;
  bool delivered_now_ = false;
  int last_op_ = -1;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Harness h;
  std::size_t i = 0;
  const auto next = [&]() -> std::uint8_t { return i < size ? data[i++] : 0; };
  const auto next32 = [&]() -> std::uint32_t {
    std::uint32_t v = 0;
    for (int k = 0; k < 4; ++k) v = (v << 8) | next();
    return v;
  };
  // The driver starts: a boot-up heartbeat, then its first session.
  {
    can::Frame boot;
    Require(can::EncodeHeartbeat(kNode, NmtState::kBootUp, boot) == can::EncodeStatus::kOk);
    h.Feed(boot);
    can::Frame operational;
    Require(can::EncodeHeartbeat(kNode, NmtState::kOperational, operational) == can::EncodeStatus::kOk);
    h.Feed(operational);
    const std::uint32_t nonce = next32();
    h.NewSession(nonce, next32() & 0x00FFFFFFu);
  }
  while (i < size) {
    const std::uint8_t op = next();
    const std::uint8_t arg = next();
    h.last_op_ = op % 12;
    switch (op % 12) {
      case 0:
      case 1:
      case 2: {  // the next status, whole and in order (lost statuses before it when arg says so)
        const std::uint32_t skip = (arg & 0x80) != 0 ? (arg & 0x7F) : 0;
        const Triple t = h.NextTriple(skip, arg);
        h.FeedWhole(t, h.MustDeliver(t));
        break;
      }
      case 3: {  // the next status with one of its frames lost
        const Triple t = h.NextTriple(0, arg);
        for (int k = 0; k < 3; ++k) {
          if (k != arg % 3) h.Feed(t.frames[k]);
        }
        break;
      }
      case 4: {  // a replay of an earlier triple of any session, whole
        if (h.history_.empty()) break;
        ++g_exercised.replays;
        const Triple t = h.history_[(static_cast<std::size_t>(arg) * 7919u + h.history_.size()) % h.history_.size()];
        h.FeedWhole(t, false);
        break;
      }
      case 5: {  // one replayed frame of an earlier triple
        if (h.history_.empty()) break;
        ++g_exercised.replays;
        const Triple& t = h.history_[static_cast<std::size_t>(arg) % h.history_.size()];
        h.Feed(t.frames[arg % 3]);
        break;
      }
      case 6: {  // a triple of another session (a forger that does not know the nonce), ahead by arg
        ++g_exercised.foreign;
        const Triple t = h.MakeTriple(h.driver_session_ ^ (0x01000193u * (arg | 1u)), h.driver_seq_ + 1 + arg, arg);
        h.FeedWhole(t, false);
        break;
      }
      case 7: {  // the next status with one bit flipped in one of its frames (CRC-8 detects every single-bit error)
        ++g_exercised.corrupted;
        Triple t = h.NextTriple(0, arg);
        can::Frame& f = t.frames[arg % 3];
        f.data[(arg >> 2) % 8] = static_cast<std::uint8_t>(f.data[(arg >> 2) % 8] ^ (1u << (arg >> 5)));
        for (const can::Frame& frame : t.frames) h.Feed(frame);  // delivered only on a CRC collision (counted)
        break;
      }
      case 8: {  // frames of two triples interleaved: status of one, position and force of the next
        const Triple a = h.NextTriple(0, arg);
        const Triple b = h.NextTriple(0, static_cast<std::uint8_t>(arg + 1));
        h.Feed(a.frames[0]);  // b's position and force are checked against a's counter: delivered only on a collision
        h.Feed(b.frames[1]);
        h.Feed(b.frames[2]);
        break;
      }
      case 9: {  // the driver starts a new session (a stop, a reset, an expiry)
        h.NewSession(next32(), (h.driver_seq_ + 1 + arg) & 0x00FFFFFFu);
        break;
      }
      case 10: {  // a replayed announcement of an earlier session: the link switches to it
        if (h.sessions_.empty()) break;
        const auto& s = h.sessions_[static_cast<std::size_t>(arg) % h.sessions_.size()];
        h.Announce(s.first, s.second);
        break;
      }
      case 11: {  // heartbeats: operational, or a boot-up (the driver restarted: the session is forgotten)
        can::Frame hb;
        const bool boot = (arg & 0x0F) == 0;
        Require(can::EncodeHeartbeat(kNode, boot ? NmtState::kBootUp : NmtState::kOperational, hb) ==
                can::EncodeStatus::kOk);
        h.Feed(hb);
        if (boot) h.NewSession(next32(), next32() & 0x00FFFFFFu);  // the restarted driver's first session
        break;
      }
    }
  }
  return 0;
}

#ifdef VISCO_FUZZ_STANDALONE
int main(int argc, char** argv) {
  const long runs = argc > 1 ? std::atol(argv[1]) : 2000;
  std::mt19937 rng(20261203);
  std::vector<std::uint8_t> input;
  for (long run = 0; run < runs; ++run) {
    input.resize(8 + 2 * (1 + rng() % 400));
    for (auto& byte : input) byte = static_cast<std::uint8_t>(rng());
    LLVMFuzzerTestOneInput(input.data(), input.size());
  }
  // A broken CRC check would accept non-genuine triples by the thousand; collisions of all three 8-bit CRCs are about
  // 2^-23 per attempt.
  const std::uint64_t attempts = g_exercised.replays + g_exercised.foreign + g_exercised.corrupted;
  Require(g_exercised.collisions <= 2 + attempts / 100'000);
  Require(g_exercised.fresh_whole > static_cast<std::uint64_t>(runs));
  std::printf(
      "link_status_fuzz: %ld seeded runs, %llu frames, %llu statuses delivered, all properties held (fresh triples "
      "read whole %llu, replays %llu, other sessions' triples %llu, corrupted %llu, announcements %llu; non-genuine "
      "triples accepted on a CRC collision: %llu)\n",
      runs, static_cast<unsigned long long>(g_exercised.frames), static_cast<unsigned long long>(g_exercised.delivered),
      static_cast<unsigned long long>(g_exercised.fresh_whole), static_cast<unsigned long long>(g_exercised.replays),
      static_cast<unsigned long long>(g_exercised.foreign), static_cast<unsigned long long>(g_exercised.corrupted),
      static_cast<unsigned long long>(g_exercised.announcements),
      static_cast<unsigned long long>(g_exercised.collisions));
  return 0;
}
#endif
