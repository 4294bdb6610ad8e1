#include "core/interp/python_host.hpp"

#include <pybind11/embed.h>
#include <pybind11/stl.h>

#include <cmath>
#include <set>
#include <stdexcept>

#include "core/util/strings.hpp"

namespace py = pybind11;

namespace cnc::interp {
namespace {

// The interpreter and Canon the scripts act on: the host attached last
// (Python and the modules `interpreter` and `emccanon` are per process, as in
// LinuxCNC).
Interpreter* g_interp = nullptr;
Canon* g_canon = nullptr;
// self.set_errormsg() of the remap procedure running
std::string g_errormsg;

Interpreter& interp() {
  if (g_interp == nullptr) throw std::runtime_error("no interpreter is attached to Python");
  return *g_interp;
}

Canon& canon() {
  if (g_canon == nullptr) throw std::runtime_error("no interpreter is attached to Python");
  return *g_canon;
}

// `this`: attributes set from Python stay (py::dynamic_attr).
struct This {};
// `this.params`
struct Params {};
// `this.tool_table`
struct ToolTableView {};
// `this.sub_context[level]` and its `named_params`
struct SubContext {
  int level = 0;
};
struct NamedParams {
  int level = 0;
};
// An entry of `named_params` while iterating: key() and data()
struct NamedParamItem {
  cnc::interp::Interpreter::NamedParameter p;
};
// `this.blocks`
struct Blocks {};

std::vector<std::string> names_at(int level) {
  std::vector<std::string> out;
  for (const auto& p : interp().named_parameters(level)) out.push_back(p.name);
  return out;
}

Pose pose9(double x, double y, double z, double a, double b, double c, double u, double v, double w) {
  Pose p;
  const double values[] = {x, y, z, a, b, c, u, v, w};
  for (int i = 0; i < kNumAxes; ++i) p[i] = values[i];
  return p;
}

double get_param(const py::object& key) {
  if (py::isinstance<py::str>(key)) {
    const std::string name = key.cast<std::string>();
    double v = 0;
    if (!interp().named_parameter(name, v)) throw py::key_error("named parameter #<" + name + "> is not defined");
    return v;
  }
  const int index = key.cast<int>();
  if (index < 1 || index > 5601) throw py::index_error("parameter #" + std::to_string(index) + " is out of range 1-5601");
  return interp().parameter(index);
}

void set_param(const py::object& key, double value) {
  try {
    if (py::isinstance<py::str>(key)) {
      interp().set_named_parameter(key.cast<std::string>(), value);
      return;
    }
    const int index = key.cast<int>();
    if (index < 1 || index > 5601) throw py::index_error("parameter #" + std::to_string(index) + " is out of range 1-5601");
    interp().set_parameter(index, value);
  } catch (const InterpError& e) {
    throw py::value_error(e.message());
  }
}

double named_or_zero(const char* name) {
  double v = 0;
  return interp().named_parameter(name, v) ? v : 0.0;
}

}  // namespace
}  // namespace cnc::interp

PYBIND11_EMBEDDED_MODULE(interpreter, m) {
  using namespace cnc::interp;
  m.doc() = "The RS274/NGC interpreter as LinuxCNC's embedded Python sees it (a subset)";
  // LinuxCNC's interpreter return codes
  m.attr("INTERP_OK") = 0;
  m.attr("INTERP_EXIT") = 1;
  m.attr("INTERP_EXECUTE_FINISH") = 2;
  m.attr("INTERP_ENDFILE") = 3;
  m.attr("INTERP_FILE_NOT_OPEN") = 4;
  m.attr("INTERP_ERROR") = 5;
  // what self.execute() raises for an interpreter error (LinuxCNC's, with
  // error_message, line_number and line_text)
  m.attr("InterpreterException") = py::reinterpret_steal<py::object>(
      PyErr_NewException("interpreter.InterpreterException", PyExc_RuntimeError, nullptr));
  // LinuxCNC's TOLERANCE_EQUAL
  m.def("equal", [](double a, double b) { return std::fabs(a - b) < 0.0001; });

  py::class_<cnc::Pose>(m, "Position")
      .def_property_readonly("x", [](const cnc::Pose& p) { return p[0]; })
      .def_property_readonly("y", [](const cnc::Pose& p) { return p[1]; })
      .def_property_readonly("z", [](const cnc::Pose& p) { return p[2]; })
      .def_property_readonly("a", [](const cnc::Pose& p) { return p[3]; })
      .def_property_readonly("b", [](const cnc::Pose& p) { return p[4]; })
      .def_property_readonly("c", [](const cnc::Pose& p) { return p[5]; })
      .def_property_readonly("u", [](const cnc::Pose& p) { return p[6]; })
      .def_property_readonly("v", [](const cnc::Pose& p) { return p[7]; })
      .def_property_readonly("w", [](const cnc::Pose& p) { return p[8]; });

  py::class_<cnc::tooltable::Tool>(m, "Tool")
      .def_property_readonly("toolno", [](const cnc::tooltable::Tool& t) { return t.is_empty() ? -1 : t.number; })
      .def_property_readonly("pocketno", [](const cnc::tooltable::Tool& t) { return t.pocket; })
      .def_property_readonly("diameter", [](const cnc::tooltable::Tool& t) { return t.diameter; })
      .def_property_readonly("frontangle", [](const cnc::tooltable::Tool& t) { return t.front_angle; })
      .def_property_readonly("backangle", [](const cnc::tooltable::Tool& t) { return t.back_angle; })
      .def_property_readonly("orientation", [](const cnc::tooltable::Tool& t) { return t.orientation; })
      .def_property_readonly("offset", [](const cnc::tooltable::Tool& t) { return t.offset; });

  py::class_<ToolTableView>(m, "ToolTable")
      .def("__len__", [](const ToolTableView&) { return interp().tool_table().size(); })
      .def("__getitem__", [](const ToolTableView&, int i) {
        if (i < 0 || i >= interp().tool_table().size()) throw py::index_error("tool table index out of range");
        return interp().tool_table().at(i);
      });

  py::class_<Params>(m, "Params")
      .def("__getitem__", [](const Params&, const py::object& key) { return get_param(key); })
      .def("__setitem__", [](const Params&, const py::object& key, double v) { set_param(key, v); })
      // names of the current call level's locals, of the globals (level 0),
      // and both
      .def("locals", [](const Params&) { return names_at(interp().call_level()); })
      .def("globals", [](const Params&) { return names_at(0); })
      .def("__call__", [](const Params&) {
        std::vector<std::string> all = names_at(interp().call_level());
        for (std::string& n : names_at(0)) all.push_back(std::move(n));
        return all;
      });

  py::class_<cnc::interp::Interpreter::NamedParameter>(m, "NamedParameter")
      .def_property_readonly("value", [](const cnc::interp::Interpreter::NamedParameter& p) { return p.value; })
      .def_property_readonly("attr", [](const cnc::interp::Interpreter::NamedParameter& p) { return p.attr; });
  py::class_<NamedParamItem>(m, "NamedParamItem")
      .def("key", [](const NamedParamItem& i) { return i.p.name; })
      .def("data", [](const NamedParamItem& i) { return i.p; });
  py::class_<NamedParams>(m, "NamedParams")
      .def("__getitem__", [](const NamedParams& n, const std::string& name) {
        for (const auto& p : interp().named_parameters(n.level)) {
          if (p.name == name) return p;
        }
        throw py::key_error(name);
      })
      .def("__contains__", [](const NamedParams& n, const std::string& name) {
        for (const auto& p : interp().named_parameters(n.level)) {
          if (p.name == name) return true;
        }
        return false;
      })
      .def("__len__", [](const NamedParams& n) { return interp().named_parameters(n.level).size(); })
      .def("__iter__", [](const NamedParams& n) {
        py::list items;
        for (const auto& p : interp().named_parameters(n.level)) items.append(py::cast(NamedParamItem{p}));
        return py::iter(items);
      });
  py::class_<SubContext>(m, "SubContext")
      .def_property_readonly("named_params", [](const SubContext& c) { return NamedParams{c.level}; });

  py::class_<cnc::interp::Interpreter::BlockView>(m, "Block")
      .def_property_readonly("o_name", [](const cnc::interp::Interpreter::BlockView& b) { return b.o_name; })
      .def_property_readonly("params", [](const cnc::interp::Interpreter::BlockView& b) { return b.params; })
      .def_property_readonly("g_modes", [](const cnc::interp::Interpreter::BlockView& b) { return b.g_modes; })
      .def_property_readonly("m_modes", [](const cnc::interp::Interpreter::BlockView& b) { return b.m_modes; });
  py::class_<Blocks>(m, "Blocks")
      .def("__getitem__", [](const Blocks&, int i) {
        // blocks[0] is the block being executed, blocks[1] .. blocks[remap_level]
        // the blocks of the remapped codes being carried out, outermost first
        // (LinuxCNC's remap stack)
        if (i == 0) return interp().current_block();
        std::vector<cnc::interp::Interpreter::BlockView> remaps = interp().remap_blocks();
        if (i < 0 || i > static_cast<int>(remaps.size())) {
          throw py::index_error("blocks[" + std::to_string(i) + "]: 0 (the block being executed) to " +
                                std::to_string(remaps.size()) + " (the remap level) are available");
        }
        return remaps[static_cast<std::size_t>(i - 1)];
      })
      .def("__len__", [](const Blocks&) { return interp().remap_blocks().size() + 1; });

  py::class_<This>(m, "Interp", py::dynamic_attr())
      .def_property_readonly("params", [](const This&) { return Params{}; })
      .def_property_readonly("tool_table", [](const This&) { return ToolTableView{}; })
      .def_property_readonly("tool_offset", [](const This&) { return interp().tool_offset(); })
      .def_property_readonly("call_level", [](const This&) { return interp().call_level(); })
      .def_property_readonly("return_value", [](const This&) { return named_or_zero("_value"); })
      .def_property_readonly("value_returned", [](const This&) { return static_cast<int>(named_or_zero("_value_returned")); })
      .def_property_readonly("remap_level", [](const This&) { return interp().remap_level(); })
      .def_property_readonly("sub_context", [](const This&) {
        std::vector<SubContext> v;
        for (int level = 0; level <= interp().call_level(); ++level) v.push_back({level});
        return v;
      })
      .def_property_readonly("blocks", [](const This&) { return Blocks{}; })
      // the interpreter's position in program coordinates (LinuxCNC's
      // current_x ..): what it commanded, or the machine's after a synch
      .def_property_readonly("current_x", [](const This&) { return interp().position()[0]; })
      .def_property_readonly("current_y", [](const This&) { return interp().position()[1]; })
      .def_property_readonly("current_z", [](const This&) { return interp().position()[2]; })
      .def_property_readonly("current_a", [](const This&) { return interp().position()[3]; })
      .def_property_readonly("current_b", [](const This&) { return interp().position()[4]; })
      .def_property_readonly("current_c", [](const This&) { return interp().position()[5]; })
      .def_property_readonly("current_u", [](const This&) { return interp().position()[6]; })
      .def_property_readonly("current_v", [](const This&) { return interp().position()[7]; })
      .def_property_readonly("current_w", [](const This&) { return interp().position()[8]; })
      // LinuxCNC's active_g_codes array: [0] the line, [1] the motion mode,
      // [2] the block's non-modal code, then plane, cutter compensation,
      // units, distance mode, feed mode, coordinate system, tool length
      // offset, retract mode, path control, (-1), spindle mode, arc distance
      // mode, lathe diameter mode (each G code x10)
      .def_property_readonly("active_g_codes", [](const This&) {
        const std::vector<int> g = interp().active_g_codes();
        const cnc::interp::Interpreter::BlockView b = interp().current_block();
        return std::vector<int>{interp().line(), g[0], b.g_modes.empty() ? -1 : b.g_modes[0], g[1], g[6], g[5], g[2],
                                g[4], g[9], g[7], g[8], g[10], -1, g[11], g[3], g[12]};
      })
      .def_property_readonly("active_m_codes", [](const This&) { return interp().active_m_codes(); })
      // what LinuxCNC's rs274 reports with [EMC]DEBUG = 0 and LOG_LEVEL = 0
      .def_property_readonly("debugmask", [](const This&) { return 0x40000000; })
      .def_property_readonly("loggingLevel", [](const This&) { return 0; })
      // feed per revolution, threading and the spindle codes without $ use
      // spindle 0 in this interpreter
      .def_property_readonly("active_spindle", [](const This&) { return 0; })
      .def_property_readonly("speed", [](const This&) {
        std::vector<double> v;
        for (int k = 0; k < Config::kMaxSpindles; ++k) v.push_back(interp().spindle_speed(k));
        return v;
      })
      .def("set_errormsg", [](const This&, const std::string& text) { g_errormsg = text; })
      // self.execute(line[, lineno]): runs a line of G-code now (the line
      // number, as LinuxCNC's, is not used: the calls belong to the block
      // being executed); returns INTERP_OK, or INTERP_EXECUTE_FINISH when the
      // machine must catch up (yield it) before the next line; an error
      // raises interpreter.InterpreterException
      .def(
          "execute",
          [](const This&, const std::string& line, std::optional<int> lineno) {
            (void)lineno;
            try {
              return interp().execute_script_line(line) == Status::ExecuteFinish ? 2 : 0;
            } catch (const InterpError& e) {
              std::string text = e.message();
              if (!e.file().empty() && e.file() != "<mdi>") text += " (" + e.file() + ":" + std::to_string(e.line()) + ")";
              py::object type = py::module_::import("interpreter").attr("InterpreterException");
              py::object exc = type(text);
              exc.attr("error_message") = text;
              exc.attr("line_number") = e.line();
              exc.attr("line_text") = e.block_text();
              PyErr_SetObject(type.ptr(), exc.ptr());
              throw py::error_already_set();
            }
          },
          py::arg("line"), py::arg("lineno") = py::none())
      .def_property_readonly("line_number", [](const This&) { return interp().line(); })
      .def_property_readonly("filename", [](const This&) { return interp().file_name(); });
}

PYBIND11_EMBEDDED_MODULE(emccanon, m) {
  using namespace cnc::interp;
  m.doc() = "Canonical machining calls from Python (a subset of LinuxCNC's emccanon)";
  m.def("STRAIGHT_TRAVERSE", [](int line, double x, double y, double z, double a, double b, double c, double u, double v,
                                double w) { canon().straight_traverse(line, pose9(x, y, z, a, b, c, u, v, w)); });
  m.def("STRAIGHT_FEED", [](int line, double x, double y, double z, double a, double b, double c, double u, double v,
                            double w) { canon().straight_feed(line, pose9(x, y, z, a, b, c, u, v, w)); });
  m.def("MESSAGE", [](const std::string& text) { canon().message(text); });
  m.def("CANON_ERROR", [](const std::string& text) { canon().canon_error(text); });
  m.def("COMMENT", [](const std::string& text) { canon().comment(text); });
  m.def("SET_FEED_RATE", [](double rate) { canon().set_feed_rate(rate); });
}

namespace cnc::interp {
namespace {

// "Type: message (at file:line)" of a Python exception: the innermost frame
// of its traceback when that is a file (not a `py,` statement).
std::string describe(py::error_already_set& e) {
  std::string text = py::str(e.type().attr("__name__")).cast<std::string>();
  const std::string message = py::str(e.value()).cast<std::string>();
  if (!message.empty()) text += ": " + message;
  py::object tb = e.trace();
  if (!tb.is_none()) {
    while (!tb.attr("tb_next").is_none()) tb = tb.attr("tb_next");
    const std::string file = py::str(tb.attr("tb_frame").attr("f_code").attr("co_filename")).cast<std::string>();
    if (!file.empty() && file.front() != '<') {
      text += " (at " + file + ":" + std::to_string(tb.attr("tb_lineno").cast<int>()) + ")";
    }
  }
  return text;
}

void ensure_python() {
  if (Py_IsInitialized() != 0) return;
  py::initialize_interpreter();
  // Calls take the GIL when they run; no thread holds it in between.
  PyEval_SaveThread();
}

class PythonHost final : public ScriptHost {
 public:
  PythonHost(PythonSettings settings, std::function<void()> before_output)
      : settings_(std::move(settings)), before_output_(std::move(before_output)) {}
  ~PythonHost() override {
    if (ns_ || !suspended_.empty()) {
      py::gil_scoped_acquire gil;
      suspended_.clear();
      ns_.reset();
    }
  }
  PythonHost(const PythonHost&) = delete;
  PythonHost& operator=(const PythonHost&) = delete;

  void attach(Interpreter& interp, Canon& canon) override {
    interp_ = &interp;
    canon_ = &canon;
    if (!settings_.configured) return;  // Python starts when a `py,` comment needs it
    start();
  }

  bool has_oword(const std::string& name) override {
    if (!started_ || !ns_) return false;  // no TOPLEVEL ran: no `oword` module
    py::gil_scoped_acquire gil;
    if (!ns_->contains("oword")) return false;
    py::object oword = (*ns_)["oword"];
    return py::hasattr(oword, name.c_str()) && PyCallable_Check(oword.attr(name.c_str()).ptr()) != 0;
  }

  std::optional<double> call_oword(const std::string& name, const std::vector<double>& args) override {
    Output out(*this);
    py::gil_scoped_acquire gil;
    try {
      py::tuple call_args(args.size() + 1);
      call_args[0] = this_object();
      for (std::size_t i = 0; i < args.size(); ++i) call_args[i + 1] = py::float_(args[i]);
      py::object result = (*ns_)["oword"].attr(name.c_str())(*call_args);
      flush_python();
      if (result.is_none()) return std::nullopt;
      if (py::isinstance<py::str>(result)) throw std::runtime_error(result.cast<std::string>());
      if (py::isinstance<py::float_>(result) || py::isinstance<py::int_>(result)) return result.cast<double>();
      throw std::runtime_error("returned " + std::string(py::str(result.get_type().attr("__name__"))) +
                               ", expected a number or None");
    } catch (py::error_already_set& e) {
      flush_python();
      throw std::runtime_error(describe(e));
    }
  }

  bool has_remap(const std::string& name) override {
    if (!started_ || !ns_) return false;
    py::gil_scoped_acquire gil;
    if (!ns_->contains("remap")) return false;
    py::object remap = (*ns_)["remap"];
    return py::hasattr(remap, name.c_str()) && PyCallable_Check(remap.attr(name.c_str()).ptr()) != 0;
  }

  RemapOutcome call_remap(const std::string& name, const std::vector<std::pair<std::string, double>>& words) override {
    if (!has_remap(name)) return {name + " is no function of the Python module `remap`", false};
    Output out(*this);
    py::gil_scoped_acquire gil;
    g_errormsg.clear();
    try {
      py::dict kwargs;
      for (const auto& [letter, value] : words) kwargs[py::str(letter)] = py::float_(value);
      py::object result = (*ns_)["remap"].attr(name.c_str())(this_object(), **kwargs);
      flush_python();
      // A generator (the function holds a yield): it runs to its first yield
      if (PyGen_Check(result.ptr()) != 0) return step(Suspended{result, name});
      return {outcome(name, result), false};
    } catch (py::error_already_set& e) {
      flush_python();
      throw std::runtime_error(describe(e));
    }
  }

  RemapOutcome resume_remap() override {
    if (suspended_.empty()) return ScriptHost::resume_remap();
    Output out(*this);
    py::gil_scoped_acquire gil;
    g_errormsg.clear();
    Suspended s = std::move(suspended_.back());
    suspended_.pop_back();
    return step(std::move(s));
  }

  void drop_suspended_remaps(std::size_t keep) override {
    if (suspended_.size() <= keep) return;
    py::gil_scoped_acquire gil;
    suspended_.resize(keep);
  }

  std::size_t suspended_remaps() const override { return suspended_.size(); }

  std::vector<std::string> script_parameters() override {
    return std::vector<std::string>(script_params_.begin(), script_params_.end());
  }

  bool script_parameter(const std::string& name, double& value) override {
    if (script_params_.count(name) == 0) return false;
    Output out(*this);
    py::gil_scoped_acquire gil;
    try {
      py::object result = py::module_::import("sys").attr("modules")["namedparams"].attr(name.c_str())(this_object());
      flush_python();
      if (py::isinstance<py::str>(result)) throw std::runtime_error(result.cast<std::string>());
      if ((py::isinstance<py::float_>(result) || py::isinstance<py::int_>(result)) && !result.is_none()) {
        value = result.cast<double>();
        return true;
      }
      throw std::runtime_error("namedparams." + name + " returned " +
                               std::string(py::str(result.get_type().attr("__name__"))) + ", expected a number");
    } catch (py::error_already_set& e) {
      flush_python();
      throw std::runtime_error(describe(e));
    }
  }

  void run_statement(const std::string& code) override {
    start();
    if (!ns_) throw std::runtime_error("Python did not start (see the first error)");
    Output out(*this);
    py::gil_scoped_acquire gil;
    try {
      py::exec(code, *ns_);
      flush_python();
    } catch (py::error_already_set& e) {
      flush_python();
      throw std::runtime_error(describe(e));
    }
  }

 private:
  // A generator remap procedure waiting for the machine (LinuxCNC's
  // CS_REEXEC_*: `yield INTERP_EXECUTE_FINISH`).
  struct Suspended {
    py::object generator;
    std::string name;
  };

  // What a remap procedure's value means (LinuxCNC's handler_returned): an
  // empty string to go on, else the error.
  static std::string outcome(const std::string& name, const py::object& result) {
    if (result.is_none()) return {};
    if (py::isinstance<py::int_>(result) && !py::isinstance<py::bool_>(result)) {
      const long code = result.cast<long>();
      if (code == 0 || code == 1) return {};  // INTERP_OK, INTERP_EXIT
      if (code == 5) return g_errormsg.empty() ? name + " returned INTERP_ERROR" : g_errormsg;
      return "Unknown error, bad error code";  // LinuxCNC's words for a code it does not know
    }
    if (py::isinstance<py::float_>(result)) return {};  // a value: accepted as LinuxCNC does
    if (py::isinstance<py::str>(result)) return result.cast<std::string>();
    return name + " returned " + std::string(py::str(result.get_type().attr("__name__"))) +
           ", expected INTERP_OK, INTERP_ERROR or None";
  }

  // Runs a generator to its next yield (the GIL held). INTERP_EXECUTE_FINISH
  // suspends it; any other value ends it with that value's meaning (the rest
  // of the generator does not run, as in LinuxCNC); its end (StopIteration)
  // is INTERP_OK.
  RemapOutcome step(Suspended s) {
    py::object value;
    try {
      value = s.generator.attr("__next__")();
      flush_python();
    } catch (py::error_already_set& e) {
      flush_python();
      if (e.matches(PyExc_StopIteration)) return {};
      throw std::runtime_error(describe(e));
    }
    if (py::isinstance<py::int_>(value) && !py::isinstance<py::bool_>(value) && value.cast<long>() == 2) {
      suspended_.push_back(std::move(s));
      return {{}, true};
    }
    return {outcome(s.name, value), false};
  }

  // Before Python writes anything, what the caller buffered goes out.
  // Also points `interpreter.this` and `emccanon` at this host's
  // interpreter (several interpreters in a process, e.g. the task's and a
  // run-from-line preview's, each have their host).
  struct Output {
    explicit Output(PythonHost& h) {
      g_interp = h.interp_;
      g_canon = h.canon_;
      if (h.before_output_) h.before_output_();
    }
  };

  static py::object this_object() { return py::module_::import("interpreter").attr("this"); }

  static void flush_python() {
    py::module_ sys = py::module_::import("sys");
    sys.attr("stdout").attr("flush")();
    sys.attr("stderr").attr("flush")();
  }

  // Starts Python (once per process), sets sys.path and `interpreter.this`,
  // runs TOPLEVEL and its __init__(self) (once per host) in the host's own
  // namespace, where `py,` statements run too. The modules a TOPLEVEL
  // imports by LinuxCNC's names are imported afresh for every host (another
  // configuration in the same process has its own).
  void start() {
    if (started_) return;
    started_ = true;
    ensure_python();
    Output out(*this);
    py::gil_scoped_acquire gil;
    try {
      py::module_ sys = py::module_::import("sys");
      py::list path = sys.attr("path");
      for (auto it = settings_.path_prepend.rbegin(); it != settings_.path_prepend.rend(); ++it) {
        path.insert(0, it->string());
      }
      for (const auto& p : settings_.path_append) path.append(p.string());
      py::dict modules = sys.attr("modules");
      for (const char* name : {"oword", "remap", "namedparams"}) {
        if (modules.contains(name)) PyDict_DelItemString(modules.ptr(), name);
      }
      py::module_ interpreter = py::module_::import("interpreter");
      if (!py::hasattr(interpreter, "this")) interpreter.attr("this") = py::cast(This{});
      ns_ = std::make_unique<py::dict>();
      py::dict& ns = *ns_;
      ns["__builtins__"] = py::module_::import("builtins");
      ns["__name__"] = "__main__";
      if (!settings_.toplevel.empty()) {
        ns["__file__"] = settings_.toplevel.string();
        py::eval_file(settings_.toplevel.string(), ns);
        if (ns.contains("__init__") && PyCallable_Check(ns["__init__"].ptr()) != 0) {
          ns["__init__"](interpreter.attr("this"));
        }
      }
      // LinuxCNC's predefined parameters in Python: the functions of the
      // module `namedparams` (when TOPLEVEL imported it) named _something
      if (modules.contains("namedparams")) {
        py::object np = modules["namedparams"];
        for (const py::handle key : py::list(py::module_::import("builtins").attr("dir")(np))) {
          const std::string name = key.cast<std::string>();
          if (name.size() > 1 && name[0] == '_' && name[1] != '_' && PyCallable_Check(np.attr(name.c_str()).ptr()) != 0) {
            script_params_.insert(name);
          }
        }
      }
      flush_python();
    } catch (py::error_already_set& e) {
      flush_python();
      throw InterpError("[PYTHON]TOPLEVEL " + settings_.toplevel.string() + ": " + describe(e), settings_.toplevel.string(),
                        0, {});
    }
  }

  PythonSettings settings_;
  std::function<void()> before_output_;
  bool started_ = false;
  Interpreter* interp_ = nullptr;
  Canon* canon_ = nullptr;
  std::unique_ptr<py::dict> ns_;  // TOPLEVEL's globals; null until started
  std::set<std::string> script_params_;  // namedparams functions: predefined parameters
  std::vector<Suspended> suspended_;       // generator remap procedures waiting, oldest first
};

std::vector<std::filesystem::path> path_list(const cnc::ini::IniFile& ini, std::string_view key) {
  std::vector<std::filesystem::path> out;
  for (const std::string& value : ini.find_all("PYTHON", key)) {
    for (const std::string& part : cnc::split(value, ':')) {
      const std::string p(cnc::trim(part));
      if (!p.empty()) out.push_back(ini.resolve_path(p));
    }
  }
  return out;
}

}  // namespace

PythonSettings python_settings(const cnc::ini::IniFile& ini) {
  PythonSettings s;
  s.configured = ini.has_section("PYTHON");
  if (!s.configured) return s;
  s.path_prepend = path_list(ini, "PATH_PREPEND");
  s.path_append = path_list(ini, "PATH_APPEND");
  if (const auto* e = ini.find_entry("PYTHON", "TOPLEVEL")) {
    s.toplevel = ini.resolve_path(e->value);
    if (!std::filesystem::is_regular_file(s.toplevel)) {
      ini.fail(e, "[PYTHON]TOPLEVEL: " + s.toplevel.string() + " is not a file (expected the Python script run at start)");
    }
  }
  return s;
}

std::shared_ptr<ScriptHost> make_python_host(PythonSettings settings, std::function<void()> before_output) {
  return std::make_shared<PythonHost>(std::move(settings), std::move(before_output));
}

}  // namespace cnc::interp
