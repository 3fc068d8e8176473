#pragma once
// One commanding writer (idl/README.md, "Fault semantics"): the robot side obeys poise/joint_command
// from one writer only, the first whose command it sees, identified by the DDS writer (its
// publication handle, unique per writer within the reader). Commands from any other writer are
// refused and counted, and the robot side reports a FAULT naming both writers; the robot keeps
// obeying its commanding writer (holding would drop a humanoid within seconds).
//
// A restarted controller is a new writer: it is adopted when the commanding writer is gone, that
// is when it is the only writer matched, or when the commanding writer has sent nothing for
// `handover_ns` (a killed process stays matched until its DDS lease expires, 10 s or more, while
// its commands stopped at once). A forger on the domain therefore cannot take over a robot whose
// controller is alive; only DDS Security keeps it out altogether.
//
// Real-time: check() does not allocate and does not throw.
#include <cstdint>

namespace poise::safety {

class CommandWriterGate {
 public:
  enum class Verdict {
    kOwner,    ///< the commanding writer: obey
    kAdopted,  ///< a new writer replaces one that is gone (a restart): obey, and log it
    kForeign   ///< another writer while the commanding one is alive: refuse (FAULT)
  };

  explicit CommandWriterGate(std::int64_t handover_ns = 100'000'000) noexcept
      : handover_ns_(handover_ns) {}

  /// A command from `writer` arriving at `now_ns`, with `matched_writers` writers matched.
  Verdict check(std::uint64_t writer, int matched_writers, std::int64_t now_ns) noexcept {
    if (owner_ == 0 || writer == owner_) {
      owner_ = writer;
      owner_seen_ns_ = now_ns;
      return Verdict::kOwner;
    }
    if (matched_writers <= 1 || now_ns - owner_seen_ns_ >= handover_ns_) {
      ++handovers_;
      owner_ = writer;
      owner_seen_ns_ = now_ns;
      return Verdict::kAdopted;
    }
    ++foreign_samples_;
    foreign_ = writer;
    return Verdict::kForeign;
  }

  std::uint64_t owner() const noexcept { return owner_; }
  std::uint64_t last_foreign_writer() const noexcept { return foreign_; }
  std::uint64_t foreign_samples() const noexcept { return foreign_samples_; }
  std::uint64_t handovers() const noexcept { return handovers_; }

 private:
  std::int64_t handover_ns_;
  std::uint64_t owner_ = 0, foreign_ = 0;
  std::int64_t owner_seen_ns_ = 0;
  std::uint64_t foreign_samples_ = 0, handovers_ = 0;
};

}  // namespace poise::safety
