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
#include <atomic>
#include <cstdint>
#include <cstdio>

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

  /// A command from `writer` arriving at `now_ns`. `matched_writers()` says how many writers are
  /// matched; it is asked only for a command of another writer than the commanding one (the
  /// vendors' status reads take a lock: not for every command at 1 kHz).
  template <typename MatchedWriters>
  Verdict check(std::uint64_t writer, MatchedWriters&& matched_writers,
                std::int64_t now_ns) noexcept {
    if (owner_ == 0 || writer == owner_) {
      owner_ = writer;
      owner_seen_ns_ = now_ns;
      return Verdict::kOwner;
    }
    if (now_ns - owner_seen_ns_ >= handover_ns_ || matched_writers() <= 1) {
      ++handovers_;
      owner_ = writer;
      owner_seen_ns_ = now_ns;
      return Verdict::kAdopted;
    }
    ++foreign_samples_;
    foreign_ = writer;
    return Verdict::kForeign;
  }

  /// The same, with the matched writers counted beforehand.
  Verdict check(std::uint64_t writer, int matched_writers, std::int64_t now_ns) noexcept {
    return check(writer, [matched_writers] { return matched_writers; }, now_ns);
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

/// Commands a CommandWriterGate refused, handed from the DDS listener thread (refuse()) to the
/// loop thread (news()), which reports them: a FAULT naming both writers, latched.
class ForeignCommands {
 public:
  /// Listener thread: a command of `writer` refused while `owner` commands the robot.
  void refuse(std::uint64_t writer, std::uint64_t owner) noexcept {
    writer_.store(writer, std::memory_order_relaxed);
    owner_.store(owner, std::memory_order_relaxed);
    refused_.fetch_add(1, std::memory_order_release);
  }
  /// Loop thread: the FAULT text when commands were refused since the last call, else nullptr.
  const char* news() noexcept {
    const std::uint64_t n = refused_.load(std::memory_order_acquire);
    if (n == reported_) return nullptr;
    reported_ = n;
    std::snprintf(text_, sizeof text_,
                  "poise/joint_command: %llu command(s) from a second writer (%016llx) refused; "
                  "writer %016llx commands the robot",
                  static_cast<unsigned long long>(n),
                  static_cast<unsigned long long>(writer_.load(std::memory_order_relaxed)),
                  static_cast<unsigned long long>(owner_.load(std::memory_order_relaxed)));
    return text_;
  }
  /// Loop thread: true once a refusal was reported (the FAULT stays).
  bool faulted() const noexcept { return reported_ > 0; }
  std::uint64_t refused() const noexcept { return refused_.load(std::memory_order_relaxed); }

 private:
  std::atomic<std::uint64_t> refused_{0}, writer_{0}, owner_{0};
  std::uint64_t reported_ = 0;
  char text_[200] = "";
};

}  // namespace poise::safety
