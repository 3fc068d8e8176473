// poise-dds-interop-peer: one side of the separate-process interop test.
//
//   interop_peer --dds cyclone --domain 123 --role pub --seed 7 [--timeout-s 30]
//   interop_peer --dds fastdds --domain 123 --role sub --seed 7 [--timeout-s 30]
//
// pub: for every topic type, fills one sample with seeded pseudo-random valid content
//      (poise::reflect::fill_random) and publishes it every 100 ms until killed or timed out.
// sub: builds the same expected samples from the same seed, receives every topic and compares
//      field by field (poise::reflect::first_difference). Prints one line per topic
//      ("OK <topic>" or "MISMATCH <topic>: <field>: <a> vs <b>"), then "ALL OK" and exits 0, or
//      exits 1 on a mismatch, 2 on timeout (listing the topics never received), 3 on a usage error.
#include <poise/msg/balance_reference.h>
#include <poise/msg/contact_problem.h>
#include <poise/msg/contact_solution.h>
#include <poise/msg/diagnostics.h>
#include <poise/msg/disturbance.h>
#include <poise/msg/estop.h>
#include <poise/msg/ground_truth.h>
#include <poise/msg/joint_command.h>
#include <poise/msg/robot_description.h>
#include <poise/msg/sensors.h>
#include <poise/msg/state.h>
#include <poise/dds/dds.hpp>
#include <poise/reflect/fill.hpp>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

namespace {

using namespace poise::msg;
using namespace std::chrono_literals;
using AllTypes =
    std::tuple<RobotDescription, Sensors, GroundTruth, State, BalanceReference, ContactProblem,
               ContactSolution, JointCommand, Disturbance, EStop, Diagnostics>;

template <class F>
void for_each_type(F&& f) {
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    (f(std::integral_constant<std::size_t, I>{}), ...);
  }
  (std::make_index_sequence<std::tuple_size_v<AllTypes>>{});
}

template <class T>
T expected_sample(std::uint64_t seed, std::size_t index) {
  std::mt19937_64 rng(seed * 1000003u + index);
  T s;
  poise::reflect::fill_random(s, rng);
  return s;
}

// Interop QoS: reliable keep-last 1 everywhere, volatile (a sample every 100 ms arrives anyway).
poise::dds::Qos interop_qos() {
  return poise::dds::Qos::reliable(1);
}

int run_pub(poise::dds::Participant& participant, std::uint64_t seed, double timeout_s) {
  std::vector<std::function<void()>> publish_all;
  std::vector<std::shared_ptr<void>> keep;
  for_each_type([&](auto index) {
    using T = std::tuple_element_t<decltype(index)::value, AllTypes>;
    auto pub = std::make_shared<poise::dds::Publisher<T>>(participant, interop_qos());
    auto sample = std::make_shared<T>(expected_sample<T>(seed, index));
    keep.push_back(pub);
    keep.push_back(sample);
    publish_all.push_back([pub, sample] { pub->publish(*sample); });
  });
  std::printf("PUBLISHING\n");
  std::fflush(stdout);
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < end) {
    for (auto& p : publish_all)
      p();
    std::this_thread::sleep_for(100ms);
  }
  return 0;
}

int run_sub(poise::dds::Participant& participant, std::uint64_t seed, double timeout_s) {
  constexpr std::size_t n = std::tuple_size_v<AllTypes>;
  std::mutex mutex;
  std::vector<int> state(n, 0);  // 0 waiting, 1 ok, -1 mismatch
  std::vector<std::string> names(n);
  std::vector<std::shared_ptr<void>> keep;
  for_each_type([&](auto index) {
    using T = std::tuple_element_t<decltype(index)::value, AllTypes>;
    constexpr std::size_t i = decltype(index)::value;
    names[i] = std::string(poise::dds::TopicTraits<T>::topic_name);
    auto expected = std::make_shared<T>(expected_sample<T>(seed, i));
    keep.push_back(expected);
    keep.push_back(std::make_shared<poise::dds::Subscriber<T>>(
        participant,
        [&, expected](const T& got) {
          std::lock_guard lock(mutex);
          if (state[i] != 0) return;
          if (auto diff = poise::reflect::first_difference(*expected, got)) {
            state[i] = -1;
            std::printf("MISMATCH %s: %s\n", names[i].c_str(), diff->c_str());
          } else {
            state[i] = 1;
            std::printf("OK %s\n", names[i].c_str());
          }
          std::fflush(stdout);
        },
        interop_qos()));
  });
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  for (;;) {
    {
      std::lock_guard lock(mutex);
      int ok = 0;
      for (std::size_t i = 0; i < n; ++i) {
        if (state[i] < 0) return 1;
        ok += state[i];
      }
      if (ok == static_cast<int>(n)) {
        std::printf("ALL OK\n");
        std::fflush(stdout);
        return 0;
      }
      if (std::chrono::steady_clock::now() >= end) {
        for (std::size_t i = 0; i < n; ++i) {
          if (state[i] == 0) std::printf("MISSING %s\n", names[i].c_str());
        }
        std::fflush(stdout);
        return 2;
      }
    }
    std::this_thread::sleep_for(10ms);
  }
}

}  // namespace

int main(int argc, char** argv) {
  try {
    poise::dds::DdsOptions dds = poise::dds::consume_dds_args(argc, argv);
    std::string role;
    std::uint64_t seed = 1;
    double timeout_s = 30;
    for (int i = 1; i + 1 < argc; i += 2) {
      if (!std::strcmp(argv[i], "--role"))
        role = argv[i + 1];
      else if (!std::strcmp(argv[i], "--seed"))
        seed = std::stoull(argv[i + 1]);
      else if (!std::strcmp(argv[i], "--timeout-s"))
        timeout_s = std::stod(argv[i + 1]);
      else
        throw std::invalid_argument(std::string("unknown option ") + argv[i]);
    }
    if (role != "pub" && role != "sub") throw std::invalid_argument("--role pub|sub is required");
    dds.participant_name = "interop-" + role;
    poise::dds::set_log_name(dds.participant_name + "/" +
                             std::string(poise::dds::to_string(dds.vendor)));
    poise::dds::Participant participant(dds);
    return role == "pub" ? run_pub(participant, seed, timeout_s)
                         : run_sub(participant, seed, timeout_s);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "interop_peer: %s\n", e.what());
    return 3;
  }
}
