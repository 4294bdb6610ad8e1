#include "cia402/sim/sim_component.hpp"

#include <cstdio>
#include <memory>
#include <vector>

#include "cia402/sim/sim_config.hpp"
#include "cia402/sim/sim_host.hpp"
#include "core/hal/component.hpp"
#include "core/ipc/service.hpp"
#include "core/util/strings.hpp"

namespace cnc::cia402::sim {
namespace {

using hal::PinDir;

struct NodePins {
  hal::FloatPin table_position, ferror, temperature;
  hal::S32Pin state;
  hal::BitPin probe_in;
  bool last_probe = false;
};

struct SimBus {
  std::unique_ptr<can::Transport> transport;
  std::unique_ptr<SimHost> host;
  std::vector<NodePins> pins;
};

class SimComponent : public hal::Component, public ipc::ControllerService {
 public:
  SimComponent(hal::ComponentContext& ctx, const hal::LoadArgs& args) : Component(ctx.hal, "cia402-sim") {
    args.allow_only({"sections"});
    if (!ctx.ini) throw hal::HalError("cia402_sim: needs the INI file (its [CIA402_SIM] sections describe the drives)");
    const auto sections = split(args.get_string("sections", "CIA402_SIM"), ',', true);
    for (std::size_t g = 0; g < sections.size(); ++g) {
      const SimBusConfig cfg = load_sim_config(*ctx.ini, std::string(trim(sections[g])));
      auto bus = std::make_unique<SimBus>();
      try {
        bus->transport = can::open_transport(cfg.interface);
      } catch (const std::exception& e) {
        throw hal::HalError("cia402_sim: [" + cfg.section + "]INTERFACE: " + e.what());
      }
      bus->host = std::make_unique<SimHost>(*bus->transport);
      for (const SimNodeConfig& n : cfg.nodes) {
        bus->host->add(n);
        char prefix[48];
        std::snprintf(prefix, sizeof prefix, "cia402-sim.%zu.node.%02u.", g, n.node_id);
        const std::string p = prefix;
        NodePins np;
        np.table_position = make_pin<double>(p + "table-position", PinDir::Out);
        np.ferror = make_pin<double>(p + "following-error", PinDir::Out);
        np.temperature = make_pin<double>(p + "temperature", PinDir::Out);
        np.state = make_pin<int32_t>(p + "state", PinDir::Out);
        np.probe_in = make_pin<bool>(p + "probe-in", PinDir::In);
        bus->pins.push_back(np);
      }
      SimBus* b = bus.get();
      b->host->after_pass = [b] {
        for (std::size_t i = 0; i < b->pins.size(); ++i) {
          NodePins& p = b->pins[i];
          DriveModel& m = b->host->at(i).model();
          p.table_position.set(m.plant().table_position() * 1000.0);
          p.ferror.set(m.following_error());
          p.temperature.set(m.temperature());
          p.state.set(static_cast<int32_t>(m.state()));
          const bool probe = p.probe_in.get();
          if (probe != p.last_probe) m.plant().set_probe_override(probe);
          p.last_probe = probe;
        }
      };
      // Running from now on: the master loaded next boots these drives.
      b->host->start();
      buses_.push_back(std::move(bus));
    }
  }
  ~SimComponent() override {
    for (auto& b : buses_) b->host->stop();
  }

  bool handle_command(const ipc::Command& cmd, ipc::CommandReporter& reporter) override {
    if (cmd.type != ipc::CommandType::SimInject) return false;
    const std::string text(cmd.text.view());
    const auto words = split_blanks(text);
    if (words.empty() || !iequals(words[0], "drive")) return false;  // another simulator's
    std::string why = "no simulated drive answers \"" + text + "\"";
    for (auto& b : buses_) {
      const auto node = words.size() > 1 ? parse_int(words[1]) : std::nullopt;
      if (!node || *node < 1 || *node > 127 || !b->host->find(static_cast<uint8_t>(*node))) continue;
      why = b->host->inject(text, cmd.d[0], cmd.d[0] != 0);
      break;
    }
    if (why.empty()) reporter.report(cmd, ipc::CommandState::Done);
    else reporter.report(cmd, ipc::CommandState::Rejected, why);
    return true;
  }

 private:
  std::vector<std::unique_ptr<SimBus>> buses_;
};

}  // namespace

void register_sim_component(hal::ComponentRegistry& registry) {
  registry.add("cia402_sim",
               "simulated CiA 402 drives per INI section: sections=CIA402_SIM[,...] (in-process or on a CAN interface)",
               [](hal::ComponentContext& ctx, const hal::LoadArgs& args) -> std::unique_ptr<hal::Component> {
                 return std::make_unique<SimComponent>(ctx, args);
               });
}

}  // namespace cnc::cia402::sim
