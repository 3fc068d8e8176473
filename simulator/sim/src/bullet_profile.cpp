#include "poise/sim/bullet_profile.hpp"

#include <LinearMath/btQuickprof.h>

#include <array>
#include <chrono>
#include <stdexcept>

namespace poise::sim {
namespace {

// One table for the process (Bullet's hooks are plain function pointers). Zone names are string
// literals in Bullet, so a zone is known by its pointer; no allocation in the hooks.
struct ZoneSlot {
  const char* name = nullptr;
  int depth = 0;
  int parent = -1;
  std::int64_t ns = 0;
  std::int64_t calls = 0;
};
struct Frame {
  int slot = -1;
  std::int64_t t0 = 0;
};
struct Table {
  bool active = false;
  std::array<ZoneSlot, 128> slots{};
  int used = 0;
  std::array<Frame, 64> stack{};
  int depth = 0;
  std::int64_t dropped = 0;
  btEnterProfileZoneFunc* old_enter = nullptr;
  btLeaveProfileZoneFunc* old_leave = nullptr;
};
Table g_table;

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

int slot_of(const char* name, int depth, int parent) {
  for (int i = 0; i < g_table.used; ++i)
    if (g_table.slots[static_cast<std::size_t>(i)].name == name &&
        g_table.slots[static_cast<std::size_t>(i)].parent == parent)
      return i;
  if (g_table.used == static_cast<int>(g_table.slots.size())) return -1;
  ZoneSlot& s = g_table.slots[static_cast<std::size_t>(g_table.used)];
  s = ZoneSlot{name, depth, parent, 0, 0};
  return g_table.used++;
}

void enter(const char* name) {
  Table& t = g_table;
  if (t.depth == static_cast<int>(t.stack.size())) {
    ++t.dropped;
    ++t.depth;  // keeps leave() balanced
    return;
  }
  const int parent = t.depth > 0 ? t.stack[static_cast<std::size_t>(t.depth - 1)].slot : -1;
  const int slot = slot_of(name, t.depth, parent);
  if (slot < 0) ++t.dropped;
  t.stack[static_cast<std::size_t>(t.depth++)] = Frame{slot, now_ns()};
}

void leave() {
  Table& t = g_table;
  if (t.depth == 0) return;
  --t.depth;
  if (t.depth >= static_cast<int>(t.stack.size())) return;
  const Frame& f = t.stack[static_cast<std::size_t>(t.depth)];
  if (f.slot < 0) return;
  ZoneSlot& s = t.slots[static_cast<std::size_t>(f.slot)];
  s.ns += now_ns() - f.t0;
  ++s.calls;
}

}  // namespace

BulletProfile::BulletProfile() {
  if (g_table.active) throw std::logic_error("BulletProfile: another profile is already active");
  g_table = Table{};
  g_table.active = true;
  g_table.old_enter = btGetCurrentEnterProfileZoneFunc();
  g_table.old_leave = btGetCurrentLeaveProfileZoneFunc();
  btSetCustomEnterProfileZoneFunc(&enter);
  btSetCustomLeaveProfileZoneFunc(&leave);
}

BulletProfile::~BulletProfile() {
  btSetCustomEnterProfileZoneFunc(g_table.old_enter);
  btSetCustomLeaveProfileZoneFunc(g_table.old_leave);
  g_table.active = false;
}

void BulletProfile::reset() {
  for (int i = 0; i < g_table.used; ++i) {
    g_table.slots[static_cast<std::size_t>(i)].ns = 0;
    g_table.slots[static_cast<std::size_t>(i)].calls = 0;
  }
  g_table.dropped = 0;
}

std::int64_t BulletProfile::dropped() const {
  return g_table.dropped;
}

std::vector<BulletProfile::Zone> BulletProfile::zones() const {
  std::vector<Zone> out;
  out.reserve(static_cast<std::size_t>(g_table.used));
  for (int i = 0; i < g_table.used; ++i) {
    const ZoneSlot& s = g_table.slots[static_cast<std::size_t>(i)];
    Zone z;
    z.name = s.name;
    z.depth = s.depth;
    if (s.parent >= 0) z.parent = g_table.slots[static_cast<std::size_t>(s.parent)].name;
    z.total_us = static_cast<double>(s.ns) * 1e-3;
    z.calls = s.calls;
    out.push_back(std::move(z));
  }
  return out;
}

}  // namespace poise::sim
