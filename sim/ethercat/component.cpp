#include "sim/ethercat/component.hpp"

#include <atomic>
#include <chrono>
#include <memory>
#include <string>
#include <thread>

#include "core/hal/component.hpp"
#include "sim/ethercat/segment.hpp"

namespace cnc::ethercat::sim {
namespace {

class SimComponent : public hal::Component {
 public:
  SimComponent(hal::ComponentContext& ctx, const hal::LoadArgs& args) : Component(ctx.hal, "ethercat_sim") {
    mark_as_simulation();
    args.allow_only({"name", "drives"});
    name_ = args.get_string("name", "sim");
    const int64_t drives = args.get_int("drives", 3, 1, 64);
    segment_ = std::make_shared<Segment>();
    segment_->add_drives(static_cast<unsigned>(drives));
    register_segment(name_, segment_);
    // The slaves' own time: watchdogs expire and drives coast while no
    // frame arrives at all (the master stopped), as on real hardware.
    // While frames arrive they carry the time, and this thread keeps off
    // the lock the master's servo thread sends under.
    clock_ = std::thread([this] {
      while (!stop_.load(std::memory_order_acquire)) {
        segment_->poll_if_idle();
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    });
  }
  ~SimComponent() override {
    stop_.store(true, std::memory_order_release);
    clock_.join();
    unregister_segment(name_);
  }

 private:
  std::string name_;
  std::shared_ptr<Segment> segment_;
  std::atomic<bool> stop_{false};
  std::thread clock_;
};

}  // namespace

void register_sim_component(hal::ComponentRegistry& registry) {
  registry.add("ethercat_sim", "simulated EtherCAT CiA 402 drives in-process: name=sim drives=3 (INTERFACE = sim:<name>)",
               [](hal::ComponentContext& ctx, const hal::LoadArgs& args) -> std::unique_ptr<hal::Component> {
                 return std::make_unique<SimComponent>(ctx, args);
               });
}

}  // namespace cnc::ethercat::sim
