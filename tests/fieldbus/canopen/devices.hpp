// Simulated devices for the master tests: a CiA-402-like process-data set
// whose position actual value follows the target position (set at each
// SYNC, so it is sampled one SYNC later), on its own virtual bus port.
#pragma once

#include <memory>

#include "fieldbus/canopen/slave_node.hpp"
#include "tests/fieldbus/canopen/sim.hpp"

namespace cnc::canopen::test {

struct EchoDevice {
  EchoDevice(Sim& sim, uint8_t id, SlaveIdentity identity = {0x00020192, 0xCC1, 0x402, 0x00010002, 0, "echo"},
             uint16_t heartbeat_ms = 0) {
    using D = DataType;
    using A = Access;
    od.add({0x6040, 0}, D::Unsigned16, A::ReadWrite, 0, true, "Controlword");
    od.add({0x6041, 0}, D::Unsigned16, A::ReadOnly, 0x0250, true, "Statusword");
    od.add({0x6060, 0}, D::Integer8, A::ReadWrite, 8, true, "Modes of operation");
    od.add({0x6064, 0}, D::Integer32, A::ReadOnly, 0, true, "Position actual value");
    od.add({0x607A, 0}, D::Integer32, A::ReadWrite, 0, true, "Target position");
    od.add({0x6502, 0}, D::Unsigned32, A::ReadOnly, 0x380, false, "Supported drive modes");
    od.add({0x2000, 0}, D::Unsigned8, A::ReadWrite, 0, false, "Setting");
    port = sim.port("node" + std::to_string(id));
    SlaveOptions o;
    o.node_id = id;
    o.identity = identity;
    o.heartbeat_ms = heartbeat_ms;
    node = std::make_unique<SlaveNode>(od, *port, o);
    node->on_sync = [this](uint8_t, int64_t) {
      od.set<int32_t>({0x6064, 0}, od.get<int32_t>({0x607A, 0}));
      od.set<uint16_t>({0x6041, 0}, static_cast<uint16_t>(0x0200 | (od.get<uint16_t>({0x6040, 0}) & 0x0F)));
    };
    node->start(sim.now());
    sim.actors.push_back([this](int64_t now) {
      if (alive) node->process(now);
    });
  }
  ObjectDictionary od;
  std::unique_ptr<can::VirtualPort> port;
  std::unique_ptr<SlaveNode> node;
  bool alive = true;
};

}  // namespace cnc::canopen::test
