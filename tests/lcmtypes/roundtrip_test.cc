// Every visco LCM type: generated (none forgotten), encodes, travels through a real LCM bus (memq://) and decodes
// to the same bytes.

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <lcm/lcm-cpp.hpp>
#include <set>
#include <string>
#include <vector>

#include "tests/lcmtypes/fill_messages.h"

namespace visco {
namespace {

std::vector<uint8_t> Encode(const auto& message) {
  std::vector<uint8_t> bytes(static_cast<size_t>(message.getEncodedSize()));
  EXPECT_EQ(message.encode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  return bytes;
}

template <typename T>
class Receiver {
 public:
  void Handle(const lcm::ReceiveBuffer*, const std::string& channel, const T* message) {
    channel_ = channel;
    received_.push_back(*message);
  }
  std::string channel_;
  std::vector<T> received_;
};

template <typename T>
void RoundTrip(const char* type_name) {
  SCOPED_TRACE(type_name);
  T sent;
  testing::Fill(sent);
  const std::vector<uint8_t> sent_bytes = Encode(sent);
  EXPECT_NE(sent_bytes, Encode(T{})) << "the filled message must differ from a default one";

  lcm::LCM bus("memq://");
  ASSERT_TRUE(bus.good());
  Receiver<T> receiver;
  const std::string channel = std::string("TEST_") + type_name;
  bus.subscribe(channel, &Receiver<T>::Handle, &receiver);
  ASSERT_EQ(bus.publish(channel, &sent), 0);
  ASSERT_GT(bus.handleTimeout(1000), 0) << "no message arrived";
  ASSERT_EQ(receiver.received_.size(), 1u);
  EXPECT_EQ(receiver.channel_, channel);
  EXPECT_EQ(Encode(receiver.received_.front()), sent_bytes);
  EXPECT_STREQ(T::getTypeName(), type_name);

  // A truncated buffer must be rejected, not read past its end.
  T truncated;
  EXPECT_LT(truncated.decode(sent_bytes.data(), 0, static_cast<int>(sent_bytes.size()) - 1), 0);
}

TEST(LcmTypes, EveryTypeRoundTripsThroughMemq) {
#define VISCO_ROUND_TRIP(type) RoundTrip<type>(#type);
  VISCO_FOR_EACH_LCM_TYPE(VISCO_ROUND_TRIP)
#undef VISCO_ROUND_TRIP
}

TEST(LcmTypes, EveryLcmFileIsGenerated) {
  std::set<std::string> on_disk;
  for (const auto& entry : std::filesystem::directory_iterator(VISCO_LCMTYPES_DIR)) {
    if (entry.path().extension() == ".lcm") on_disk.insert(entry.path().stem().string());
  }
  std::set<std::string> generated;
#define VISCO_NAME(type) generated.insert(#type);
  VISCO_FOR_EACH_LCM_TYPE(VISCO_NAME)
#undef VISCO_NAME
  EXPECT_EQ(on_disk, generated);
  EXPECT_EQ(static_cast<int>(generated.size()), VISCO_LCM_TYPE_COUNT);
}

TEST(LcmTypes, FingerprintsAreDistinct) {
  std::set<int64_t> hashes;
#define VISCO_HASH(type) hashes.insert(type::getHash());
  VISCO_FOR_EACH_LCM_TYPE(VISCO_HASH)
#undef VISCO_HASH
  EXPECT_EQ(static_cast<int>(hashes.size()), VISCO_LCM_TYPE_COUNT) << "lcm-spy tells types apart by fingerprint";
}

}  // namespace
}  // namespace visco
