#pragma once
// A slow, obvious reading of drivers/visco.dbc for tests: parses the BO_/SG_ lines (Intel byte order only) and
// extracts signals bit by bit. The protocol's fast decoders are compared against it, which also proves that the DBC
// file and the C++ code describe the same frames.

#include <cstdint>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <string>

namespace visco::drivers::testing {

struct DbcSignal {
  int start = 0;
  int length = 0;
  bool is_signed = false;
  double scale = 1.0;
  double offset = 0.0;
};

struct DbcMessage {
  std::uint32_t id = 0;
  std::string name;
  int dlc = 0;
  std::map<std::string, DbcSignal> signals;
};

class Dbc {
 public:
  explicit Dbc(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error("cannot open " + path);
    const std::regex message(R"(^BO_ (\d+) (\w+): (\d+) \w+)");
    const std::regex signal(R"(^ SG_ (\w+) : (\d+)\|(\d+)@([01])([+-]) \(([^,]+),([^)]+)\))");
    std::string line;
    DbcMessage* current = nullptr;
    while (std::getline(in, line)) {
      std::smatch m;
      if (std::regex_search(line, m, message)) {
        const auto id = static_cast<std::uint32_t>(std::stoul(m[1]));
        current = &messages_[id];
        current->id = id;
        current->name = m[2];
        current->dlc = std::stoi(m[3]);
      } else if (current != nullptr && std::regex_search(line, m, signal)) {
        if (m[4] != "1") throw std::runtime_error("only Intel byte order is supported: " + line);
        DbcSignal s;
        s.start = std::stoi(m[2]);
        s.length = std::stoi(m[3]);
        s.is_signed = m[5] == "-";
        s.scale = std::stod(m[6]);
        s.offset = std::stod(m[7]);
        current->signals[m[1]] = s;
      } else if (line.empty()) {
        current = nullptr;
      }
    }
  }

  const DbcMessage& message(std::uint32_t id) const {
    auto it = messages_.find(id);
    if (it == messages_.end()) throw std::runtime_error("no message " + std::to_string(id) + " in the DBC");
    return it->second;
  }
  const std::map<std::uint32_t, DbcMessage>& messages() const { return messages_; }

  /// The raw value of `signal`, bit by bit (bit i of the frame is bit i%8 of byte i/8).
  static std::int64_t Raw(const DbcSignal& signal, const std::uint8_t* data) {
    std::uint64_t raw = 0;
    for (int i = 0; i < signal.length; ++i) {
      const int bit = signal.start + i;
      if ((data[bit / 8] >> (bit % 8)) & 1) raw |= std::uint64_t{1} << i;
    }
    if (signal.is_signed && ((raw >> (signal.length - 1)) & 1)) {
      return static_cast<std::int64_t>(raw) - (std::int64_t{1} << signal.length);
    }
    return static_cast<std::int64_t>(raw);
  }
  static double Physical(const DbcSignal& signal, const std::uint8_t* data) {
    return static_cast<double>(Raw(signal, data)) * signal.scale + signal.offset;
  }

 private:
  std::map<std::uint32_t, DbcMessage> messages_;
};

/// CRC-8/SAE-J1850 as polynomial division over a bit string, the textbook way.
inline std::uint8_t ReferenceCrc8(const std::uint8_t* bytes, int size) {
  std::uint16_t reg = 0xFF;  // init
  for (int i = 0; i < size; ++i) {
    for (int bit = 7; bit >= 0; --bit) {
      const int in = (bytes[i] >> bit) & 1;
      const int top = (reg >> 7) & 1;
      reg = static_cast<std::uint16_t>((reg << 1) & 0xFF);
      if (top ^ in) reg ^= 0x1D;
    }
  }
  return static_cast<std::uint8_t>(reg ^ 0xFF);
}

}  // namespace visco::drivers::testing
