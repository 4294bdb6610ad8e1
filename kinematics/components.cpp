// The kinematics modules as HAL components: `loadrt <module> <args>`, one
// IN pin per geometry number (settable with setp, or netted, as LinuxCNC's
// modules), initial values from loadrt arguments of the same name and, where
// LinuxCNC has them, from the INI.
#include <algorithm>
#include <functional>

#include "core/ini/ini_file.hpp"
#include "core/util/strings.hpp"
#include "kinematics/five_axis.hpp"
#include "kinematics/genserkins.hpp"
#include "kinematics/matrixkins.hpp"
#include "kinematics/scarakins.hpp"
#include "kinematics/trivkins.hpp"

namespace cnc::kin {
namespace {

using hal::ComponentContext;
using hal::HalError;
using hal::LoadArgs;

// Dry run of a module's bind(): learns its pin names and applies the loadrt
// values, before any pin exists (so a bad argument leaves the HAL untouched).
class ArgCollector final : public HalBinder {
 public:
  explicit ArgCollector(const LoadArgs& args) : args_(args) {}
  const std::string& prefix() const override { return args_.component(); }
  void param(const std::string& name, KinParam& p) override {
    names.push_back(name);
    if (args_.get(name)) p.set(args_.get_double(name, p.get()));
  }
  hal::BitPin out_bit(const std::string&, bool) override { return {}; }
  hal::U32Pin out_u32(const std::string&) override { return {}; }

  std::vector<std::string> names;

 private:
  const LoadArgs& args_;
};

class ModuleComponent final : public KinematicsComponent, private HalBinder {
 public:
  ModuleComponent(hal::Hal& hal, const std::string& name, std::unique_ptr<KinematicsModule> module)
      : KinematicsComponent(hal, name), module_(std::move(module)) {
    module_->bind(*this);
  }
  Kinematics& kinematics() noexcept override { return *module_; }

 private:
  const std::string& prefix() const override { return name(); }
  void param(const std::string& n, KinParam& p) override {
    p.bind(make_pin<double>(name() + "." + n, hal::PinDir::In, p.get()));
  }
  hal::BitPin out_bit(const std::string& full_name, bool initial) override {
    return make_pin<bool>(full_name, hal::PinDir::Out, initial);
  }
  hal::U32Pin out_u32(const std::string& full_name) override {
    return make_pin<uint32_t>(full_name, hal::PinDir::Out, 0u);
  }

  std::unique_ptr<KinematicsModule> module_;
};

using MakeModule = std::function<std::unique_ptr<KinematicsModule>(ComponentContext&, const LoadArgs&)>;

void refuse_second_module(const ComponentContext& ctx, const std::string& who) {
  if (const KinematicsComponent* c = find_kinematics(ctx.hal)) {
    throw HalError(who + ": kinematics module \"" + c->name() + "\" is already loaded; load exactly one");
  }
}

// [KINS]JOINTS counts every joint motion drives: at least the module's.
void check_kins_joints(const ComponentContext& ctx, const std::string& who, const KinematicsModule& m) {
  if (ctx.ini == nullptr) return;
  const ini::Entry* e = ctx.ini->find_entry("KINS", "JOINTS");
  if (e == nullptr) return;
  const int64_t joints = ctx.ini->get_int("KINS", "JOINTS", 0, ini::Range{1, kMaxJoints});
  if (joints < m.num_joints()) {
    throw HalError(who + ": the module drives " + std::to_string(m.num_joints()) + " joints (" +
                   m.joint_map().letters() + ") but " + e->file + ":" + std::to_string(e->line) +
                   ": [KINS]JOINTS = " + e->value + "; set [KINS]JOINTS to " + std::to_string(m.num_joints()));
  }
}

void add_module(hal::ComponentRegistry& registry, const std::string& name, const std::string& help,
                std::vector<std::string> own_args, MakeModule make) {
  registry.add(name, help,
               [own_args, make](ComponentContext& ctx, const LoadArgs& args) -> std::unique_ptr<hal::Component> {
                 refuse_second_module(ctx, args.component());
                 std::unique_ptr<KinematicsModule> m = make(ctx, args);
                 ArgCollector collector(args);
                 m->bind(collector);
                 std::vector<std::string> known = own_args;
                 known.insert(known.end(), collector.names.begin(), collector.names.end());
                 args.allow_only(known);
                 check_kins_joints(ctx, args.component(), *m);
                 return std::make_unique<ModuleComponent>(ctx.hal, args.component(), std::move(m));
               });
}

JointMap coordinates(const LoadArgs& args, const std::string& def, bool duplicates, const std::string& required) {
  return JointMap::parse(args.get_string("coordinates", def), args.component(), duplicates, required);
}

std::unique_ptr<KinematicsModule> make_trt(const LoadArgs& args, TiltAxis tilt) {
  const std::string letters = tilt == TiltAxis::A ? "XYZAC" : "XYZBC";
  const char* name = tilt == TiltAxis::A ? "xyzac-trt-kins" : "xyzbc-trt-kins";
  return std::make_unique<TableTableKins>(name, tilt, coordinates(args, letters, true, letters));
}

std::unique_ptr<KinematicsModule> make_head_table(const LoadArgs& args) {
  const std::string head = to_upper(args.get_string("head", "B"));
  if (head != "A" && head != "B") {
    throw HalError(args.component() + ": head=" + head + ": expected A (head tilts about X) or B (about Y)");
  }
  const std::string letters = "XYZ" + head + "C";
  return std::make_unique<HeadTableKins>("headtable-kins", head == "A" ? TiltAxis::A : TiltAxis::B,
                                         coordinates(args, letters, true, letters));
}

std::unique_ptr<KinematicsModule> make_genser(ComponentContext& ctx, const LoadArgs& args) {
  std::array<bool, GenserKins::kJoints> prismatic{};
  const std::string types = to_upper(args.get_string("joint-types", "RRRRRR"));
  if (types.size() != prismatic.size() || types.find_first_not_of("RP") != std::string::npos) {
    throw HalError(args.component() + ": joint-types=" + types +
                   ": expected 6 letters, R (revolute) or P (prismatic) per joint");
  }
  for (std::size_t i = 0; i < prismatic.size(); ++i) prismatic[i] = types[i] == 'P';
  auto m = std::make_unique<GenserKins>(prismatic);
  if (ctx.ini != nullptr) {
    for (int i = 0; i < GenserKins::kJoints; ++i) {
      const std::string section = "JOINT_" + std::to_string(i);
      auto& p = m->params();
      const auto u = static_cast<std::size_t>(i);
      p.min_limit[u].set(ctx.ini->get_double(section, "MIN_LIMIT", p.min_limit[u].get()));
      p.max_limit[u].set(ctx.ini->get_double(section, "MAX_LIMIT", p.max_limit[u].get()));
    }
  }
  return m;
}

}  // namespace

void register_kinematics_components(hal::ComponentRegistry& registry) {
  add_module(registry, "trivkins",
             "trivial kinematics: coordinates=XYZ (a letter twice: gantry) kinstype=1|B|F|I",
             {"coordinates", "kinstype"}, [](ComponentContext&, const LoadArgs& args) {
               const KinematicsType type = parse_kinstype(args.get_string("kinstype", "1"), args.component());
               return std::make_unique<TrivKins>(coordinates(args, "XYZABCUVW", true, ""), type);
             });
  add_module(registry, "matrixkins",
             "XYZ squareness/scale correction joints = C pose: coordinates=XYZ, pins c-xx ... c-zz",
             {"coordinates"}, [](ComponentContext&, const LoadArgs& args) {
               return std::make_unique<MatrixKins>(coordinates(args, "XYZ", true, "XYZ"));
             });
  add_module(registry, "xyzac-trt-kins",
             "5-axis tilting table A + rotary table C, tool-centre point: coordinates=XYZAC, pins "
             "x/y/z-rot-point x/y/z-offset tool-offset; switchable (1 = identity)",
             {"coordinates"},
             [](ComponentContext&, const LoadArgs& args) { return make_trt(args, TiltAxis::A); });
  add_module(registry, "xyzbc-trt-kins",
             "5-axis tilting table B + rotary table C, tool-centre point: coordinates=XYZBC, pins "
             "x/y/z-rot-point x/y/z-offset tool-offset; switchable (1 = identity)",
             {"coordinates"},
             [](ComponentContext&, const LoadArgs& args) { return make_trt(args, TiltAxis::B); });
  add_module(registry, "headtable-kins",
             "5-axis tilting head (head=B or A) + rotary table C, tool-centre point: coordinates=XYZBC, pins "
             "x/y-rot-point pivot-length tool-offset; switchable (1 = identity)",
             {"coordinates", "head"}, [](ComponentContext&, const LoadArgs& args) { return make_head_table(args); });
  add_module(registry, "scarakins", "SCARA arm: pins d1 ... d6 (LinuxCNC's D1 ... D6); switchable (1 = identity)",
             {}, [](ComponentContext&, const LoadArgs&) { return std::make_unique<ScaraKins>(); });
  add_module(registry, "genserkins",
             "6-joint serial arm from DH parameters: pins a-N alpha-N d-N, min/max-limit-N, joint-types=RRRRRR; "
             "switchable (1 = identity)",
             {"joint-types"}, make_genser);
}

}  // namespace cnc::kin
