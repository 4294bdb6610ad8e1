// Bus load of CSP axes on one 1 Mbit/s CANopen bus at 1 kHz and 500 Hz,
// measured by the in-process virtual bus's own accounting (every frame
// charged its bit time, arbitration by identifier) while the real master
// and simulated devices run the cycle, printed beside the calculator and
// the reference table (canopen.md §8). Simulated time: deterministic and
// independent of the machine. Run: build/bin/canopen_bus_load
#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "fieldbus/can/bus_load.hpp"
#include "sim/can/virtual_bus.hpp"
#include "fieldbus/canopen/master.hpp"
#include "fieldbus/canopen/slave_node.hpp"

using namespace cnc;
using namespace cnc::canopen;

namespace {

struct Device {
  Device(can::VirtualBus& bus, uint8_t id) {
    using D = DataType;
    using A = Access;
    od.add({0x6040, 0}, D::Unsigned16, A::ReadWrite, 0, true);
    od.add({0x6041, 0}, D::Unsigned16, A::ReadOnly, 0x0237, true);
    od.add({0x6064, 0}, D::Integer32, A::ReadOnly, 0, true);
    od.add({0x607A, 0}, D::Integer32, A::ReadWrite, 0, true);
    port = bus.open_port("axis" + std::to_string(id));
    SlaveOptions o;
    o.node_id = id;
    o.identity = {0x00020192, 0xCC1, 0x402, 1, id, "bench axis"};
    node = std::make_unique<SlaveNode>(od, *port, o);
    node->on_sync = [this](uint8_t, int64_t) { od.set<int32_t>({0x6064, 0}, od.get<int32_t>({0x607A, 0})); };
  }
  ObjectDictionary od;
  std::unique_ptr<can::VirtualPort> port;
  std::unique_ptr<SlaveNode> node;
};

struct Result {
  double load = 0;          // measured busy fraction
  uint64_t frames = 0;
  uint32_t missed = 0;      // TPDOs that did not answer their SYNC in time
  double pdo_ok = 0;        // share of cycles with every input fresh
  bool booted = false;
};

Result run(int axes, int64_t cycle_ns, can::Stuffing stuffing, double seconds) {
  can::VirtualBusOptions bo;
  bo.stuffing = stuffing;
  auto bus = can::VirtualBus::create(bo);
  std::vector<std::unique_ptr<Device>> devices;
  BusConfig c;
  c.interface = "virtual:bench";
  c.cycle_ns = cycle_ns;
  c.max_bus_load = 10.0;  // measure overloaded buses too
  c.max_cycle_load = 10.0;
  c.boot_timeout_ns = 1'000'000'000;
  c.pdo_miss_limit = 0;
  for (int i = 1; i <= axes; ++i) {
    devices.push_back(std::make_unique<Device>(*bus, static_cast<uint8_t>(i)));
    NodeConfig n;
    n.id = static_cast<uint8_t>(i);
    n.heartbeat_ms = 100;
    n.heartbeat_timeout_ms = 1000;
    PdoConfig r, t;
    r.map = {{0x6040, 0, 16}, {0x607A, 0, 32}};
    t.map = {{0x6041, 0, 16}, {0x6064, 0, 32}};
    n.rpdos = {r};
    n.tpdos = {t};
    c.nodes.push_back(n);
  }
  Master m(c, bus->open_port("master-cyclic"), bus->open_port("master-acyclic"), nullptr);
  for (auto& d : devices) d->node->start(0);
  const int64_t step = 10'000;
  auto step_all = [&] {
    bus->advance(step);
    const int64_t now = bus->now_ns();
    for (auto& d : devices) d->node->process(now);
    m.poll(now);
  };
  m.begin_boot();
  while ((m.boot_state() == BootState::Running || m.boot_state() == BootState::Idle) && bus->now_ns() < 10'000'000'000) step_all();
  Result res;
  res.booted = m.boot_state() == BootState::Succeeded;
  if (!res.booted) return res;
  // Let the bus settle into the cycle, then measure.
  auto cycle = [&](bool count, uint64_t& fresh) {
    m.cyclic_read(bus->now_ns());
    if (count) fresh += m.cyclic_status().inputs_fresh;
    m.cyclic_write(bus->now_ns());
    for (int64_t t = 0; t < cycle_ns; t += step) step_all();
  };
  uint64_t fresh = 0;
  for (int i = 0; i < 100; ++i) cycle(false, fresh);
  bus->reset_stats();
  const uint32_t missed_before = m.cyclic_status().pdo_missed;
  const int64_t cycles = static_cast<int64_t>(seconds * 1e9) / cycle_ns;
  for (int64_t i = 0; i < cycles; ++i) cycle(true, fresh);
  const can::VirtualBusStats s = bus->stats();
  res.load = s.load();
  res.frames = s.frames;
  res.missed = m.cyclic_status().pdo_missed - missed_before;
  res.pdo_ok = static_cast<double>(fresh) / static_cast<double>(cycles);
  return res;
}

}  // namespace

int main() {
  std::printf("CSP axes on one 1 Mbit/s CANopen bus: RPDO 6 B (controlword, target) + TPDO 6 B (statusword,\n"
              "position) per axis, SYNC every cycle, heartbeats at 100 ms. 'calc' is the calculator\n"
              "(fieldbus/can/bus_load.hpp), 'virtual bus' the load the in-process bus accounted while the\n"
              "master and simulated drives ran 1 s of the cycle (worst-case stuffing / exact stuffing of the\n"
              "real bit stream). 'fresh' = cycles in which every TPDO answered the last SYNC in time.\n\n");
  for (int64_t cycle : {1'000'000, 2'000'000}) {
    std::printf("%s (cycle %lld us)\n", cycle == 1'000'000 ? "1 kHz" : "500 Hz", static_cast<long long>(cycle / 1000));
    std::printf("  axes | calc nominal | calc worst | calc busiest cycle | virtual bus worst | virtual bus exact | fresh  | TPDOs late | fits\n");
    int capacity = 0;
    for (int axes = 1; axes <= 8; ++axes) {
      BusConfig c;
      c.cycle_ns = cycle;
      c.interface = "virtual:x";
      for (int i = 1; i <= axes; ++i) {
        NodeConfig n;
        n.id = static_cast<uint8_t>(i);
        PdoConfig p;
        p.map = {{0x6040, 0, 16}, {0x607A, 0, 32}};
        n.rpdos = {p};
        n.tpdos = {p};
        c.nodes.push_back(n);
      }
      const can::BusLoad calc = c.load();
      const Result worst = run(axes, cycle, can::Stuffing::WorstCase, 1.0);
      const Result exact = run(axes, cycle, can::Stuffing::Exact, 1.0);
      const bool fits = c.load_problem().empty();
      if (fits && worst.missed == 0) capacity = axes;
      std::printf("  %4d | %10.1f %% | %8.1f %% | %16.1f %% | %15.1f %% | %15.1f %% | %5.1f%% | %10u | %s\n", axes,
                  calc.nominal() * 100, calc.worst_case() * 100, calc.worst_cycle() * 100, worst.load * 100, exact.load * 100,
                  worst.pdo_ok * 100, worst.missed, fits ? "yes" : "no");
    }
    std::printf("  -> %d CSP axes within the budgets (80 %% average, 90 %% busiest cycle) with every TPDO in time\n\n", capacity);
  }
  std::printf("Reference table (canopen.md §8), axes per bus, nominal / worst case, from axes_per_bus():\n");
  std::printf("  %-28s | %-13s | %-13s | %-13s | %-13s\n", "PDOs per axis", "1 kHz 100 %", "1 kHz 80 %", "500 Hz 100 %",
              "500 Hz 80 %");
  struct Row {
    const char* name;
    std::vector<uint32_t> r, t;
  };
  const Row rows[] = {{"RPDO 6 B + TPDO 6 B", {6}, {6}},
                      {"7 B + 7 B (with mode byte)", {7}, {7}},
                      {"8 B + 8 B", {8}, {8}},
                      {"RPDO 6 B + 2 x TPDO 8 B", {6}, {8, 8}}};
  for (const Row& row : rows) {
    const can::AxisBits b = can::axis_bits(row.r, row.t);
    std::printf("  %-28s", row.name);
    for (int64_t cycle : {1'000'000, 2'000'000}) {
      for (double budget : {1.0, 0.8}) {
        std::printf(" | %5.1f / %5.1f", can::axes_per_bus(b.nominal, can::nominal_frame_bits(false, 0), cycle, 1'000'000, budget),
                    can::axes_per_bus(b.worst_case, can::worst_case_frame_bits(false, 0), cycle, 1'000'000, budget));
      }
    }
    std::printf("\n");
  }
  return 0;
}
