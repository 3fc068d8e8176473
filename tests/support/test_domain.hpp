#pragma once
// A DDS domain of one's own for every test process, so that tests run in parallel (ctest -j)
// never discover each other's participants: the lock-file claim `poise run` uses too.

#include "poise/dds/domain_claim.hpp"

namespace poise::testing {

/// The domain this test process claimed (on the first call; held for the life of the process).
inline int claim_test_domain() {
  static const int claimed = dds::claim_free_domain();
  return claimed;
}

}  // namespace poise::testing
