// Embedded Python in the interpreter ([PYTHON], core/interp/python_host.hpp):
// O-word subroutines written as Python functions, `;py,` statements, the
// interpreter as Python sees it, and errors that name the file and line.
#include <gtest/gtest.h>

#include <cstdio>
#include <functional>
#include <fstream>
#include <sstream>

#include <unistd.h>

#include "core/ini/ini_file.hpp"
#include "core/interp/python_host.hpp"
#include "core/interp/recording_canon.hpp"
#include "core/interp/rs274_run.hpp"
#include "tests/support/testing.hpp"

namespace fs = std::filesystem;
using cnc::interp::Rs274Options;

namespace {

struct Result {
  bool ok = false;
  std::string out;  // canonical calls (index dropped) and what Python printed
  std::string err;
};

// Runs test.ngc in a fresh folder holding `files` (and test.ini when given)
// with the Python host, as cnc-rs274 does; stdout is captured through a file
// so that Python's prints and the calls interleave as they would.
Result run(const std::string& program, const std::string& ini, const std::vector<std::pair<std::string, std::string>>& files) {
  cnc::testing::TempDir dir;
  for (const auto& [name, text] : files) dir.write(name, text);
  dir.write("test.ngc", program);
  Rs274Options o;
  o.program = "test.ngc";
  o.machine_units = cnc::interp::Units::Mm;
  o.rs274_error_format = false;  // file:line: message
  if (!ini.empty()) o.ini = dir.write("test.ini", ini);
  o.make_script = [](const cnc::ini::IniFile* ini_file, std::function<void()> flush) {
    return cnc::interp::make_python_host(ini_file ? cnc::interp::python_settings(*ini_file) : cnc::interp::PythonSettings{},
                                         std::move(flush));
  };
  const fs::path back = fs::current_path();
  fs::current_path(dir.path());
  Result r;
  std::fflush(stdout);
  // Python writes to file descriptor 1: point it at a file for the run
  const int saved = dup(1);
  std::FILE* capture = std::fopen("out.txt", "w");
  dup2(fileno(capture), 1);
  std::string error;
  char* ebuf = nullptr;
  std::size_t esize = 0;
  std::FILE* emem = open_memstream(&ebuf, &esize);
  try {
    r.ok = cnc::interp::run_rs274(o, stdout, error, emem);
  } catch (const std::exception& e) {
    r.err = std::string("thrown: ") + e.what();
  }
  std::fflush(stdout);
  dup2(saved, 1);
  close(saved);
  std::fclose(capture);
  std::fclose(emem);
  r.err += std::string(ebuf, esize);
  std::free(ebuf);
  std::ifstream in("out.txt");
  std::string line;
  while (std::getline(in, line)) {
    const std::size_t n = line.find(" N.");
    r.out += (n == std::string::npos ? line : line.substr(n + 1)) + "\n";
  }
  fs::current_path(back);
  return r;
}

const char* kIni = "[RS274NGC]\nSUBROUTINE_PATH = .\n[PYTHON]\nPATH_PREPEND = .\nTOPLEVEL = subs.py\n";

}  // namespace

TEST(InterpPython, AnOwordFunctionGetsTheCallsArgumentsAndItsNumberIsTheCallsValue) {
  const Result r = run("o<area> call [3] [4]\n(debug, value=#<_value> returned=#<_value_returned>)\n"
                       "o<nothing> call\n(debug, value=#<_value> returned=#<_value_returned>)\nM2\n",
                       kIni,
                       {{"subs.py", "import oword\n"},
                        {"oword.py", "def area(self, w, h):\n    print('area of', w, h)\n    return w * h\n"
                                     "def nothing(self, *args):\n    pass\n"}});
  ASSERT_TRUE(r.ok) << r.err << r.out;
  EXPECT_NE(r.out.find("area of 3.0 4.0\nN..... MESSAGE(\" value=12.000000 returned=1.000000\")"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("MESSAGE(\" value=0.000000 returned=0.000000\")"), std::string::npos) << r.out;
}

TEST(InterpPython, PyCommentsRunInOneNamespaceAndSeeParametersToolsAndSelfAttributes) {
  const Result r = run("#<depth> = 2.5\n#1 = 7\n;py,from interpreter import *\n"
                       ";py,this.seen = this.params['depth'] + this.params[1]\n"
                       ";py,print('seen', this.seen, 'level', this.call_level)\n"
                       ";py,this.params['_answer'] = 42\n(debug, answer=#<_answer>)\n"
                       ";py,assert equal(this.tool_offset.z, 0.0)\nM2\n",
                       kIni, {{"subs.py", "\n"}});
  ASSERT_TRUE(r.ok) << r.err << r.out;
  EXPECT_NE(r.out.find("seen 9.5 level 0"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("MESSAGE(\" answer=42.000000\")"), std::string::npos) << r.out;
}

TEST(InterpPython, EmccanonCallsFromAFunctionAreMachineCallsInOrder) {
  const Result r = run("G1 X1 F100\no<mv> call [5]\nM2\n", kIni,
                       {{"subs.py", "import oword\n"},
                        {"oword.py", "import emccanon\ndef mv(self, x):\n    emccanon.MESSAGE('moving')\n"
                                     "    emccanon.STRAIGHT_FEED(1, x, 2, 3, 0, 0, 0, 0, 0, 0)\n"}});
  ASSERT_TRUE(r.ok) << r.err << r.out;
  const std::size_t first = r.out.find("STRAIGHT_FEED(1.0000, 0.0000");
  const std::size_t msg = r.out.find("MESSAGE(\"moving\")");
  const std::size_t second = r.out.find("STRAIGHT_FEED(5.0000, 2.0000, 3.0000");
  ASSERT_NE(second, std::string::npos) << r.out;
  EXPECT_LT(first, msg);
  EXPECT_LT(msg, second);
}

TEST(InterpPython, APythonErrorStopsTheProgramNamingTheLineAndTheException) {
  const Result r = run("(debug, before)\n;py,assert 1 == 2, 'one is not two'\n(debug, after)\nM2\n", kIni,
                       {{"subs.py", "\n"}});
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("test.ngc:2: py,assert 1 == 2, 'one is not two': AssertionError: one is not two"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(r.out.find("after"), std::string::npos) << r.out;
}

TEST(InterpPython, AnExceptionInAFunctionNamesTheCallAndWhereInThePythonFileItWasRaised) {
  const Result r = run("o<div> call [1]\nM2\n", kIni,
                       {{"subs.py", "import oword\n"}, {"oword.py", "def div(self, x):\n    y = 0\n    return x / y\n"}});
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("test.ngc:1: o<div> (Python): ZeroDivisionError: float division by zero (at "), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("oword.py:3)"), std::string::npos) << r.err;
}

TEST(InterpPython, AStringReturnedByAnOwordFunctionIsAnError) {
  const Result r = run("o<check> call\nM2\n", kIni,
                       {{"subs.py", "import oword\n"}, {"oword.py", "def check(self):\n    return 'probe not connected'\n"}});
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("o<check> (Python): probe not connected"), std::string::npos) << r.err;
}

TEST(InterpPython, AMissingToplevelIsAConfigurationErrorNamingTheKey) {
  const Result r = run("M2\n", "[PYTHON]\nTOPLEVEL = nothere.py\n", {});
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("[PYTHON]TOPLEVEL"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("nothere.py is not a file"), std::string::npos) << r.err;
}

TEST(InterpPython, WithoutAnOwordFunctionOfThatNameTheGcodeSubroutineRuns) {
  const Result r = run("o<sub1> call\nM2\n", kIni,
                       {{"subs.py", "import oword\n"},
                        {"oword.py", "def other(self):\n    return 1\n"},
                        {"sub1.ngc", "o<sub1> sub\n(debug, from ngc)\no<sub1> endsub\nM2\n"}});
  ASSERT_TRUE(r.ok) << r.err << r.out;
  EXPECT_NE(r.out.find("MESSAGE(\" from ngc\")"), std::string::npos) << r.out;
}

// ---------------------------------------------------------------- REMAP

namespace {
const char* kRemapIni =
    "[RS274NGC]\nSUBROUTINE_PATH = .\n"
    "REMAP = M410 modalgroup=10 argspec=Pq py=m410\n"
    "REMAP = M411 modalgroup=10 argspec=P prolog=pro411 ngc=rm411 epilog=epi411\n"
    "[PYTHON]\nPATH_PREPEND = .\nTOPLEVEL = subs.py\n";
const char* kRemapPy =
    "import emccanon\nfrom interpreter import *\n"
    "def m410(self, **words):\n"
    "    emccanon.MESSAGE('m410 p=%g q=%s level=%d' % (words['p'], words.get('q'), self.remap_level))\n"
    "    if words['p'] < 0:\n"
    "        self.set_errormsg('M410: P must not be negative')\n"
    "        return INTERP_ERROR\n"
    "    return INTERP_OK\n"
    "def pro411(self, **words):\n"
    "    self.params['twice'] = words['p'] * 2\n"
    "    return INTERP_OK\n"
    "def epi411(self, **words):\n"
    "    emccanon.MESSAGE('epilog sees %g' % self.params['result'])\n"
    "    return INTERP_OK\n";
}  // namespace

TEST(InterpPython, APythonRemapBodyGetsTheArgspecWordsAndTheBlockGoesOn) {
  const Result r = run("M410 P2 G0 X5\nM410 P3 Q4\nM2\n", kRemapIni,
                       {{"subs.py", "import remap\n"}, {"remap.py", kRemapPy}, {"rm411.ngc", "o<rm411> sub\no<rm411> endsub\n"}});
  ASSERT_TRUE(r.ok) << r.err << r.out;
  const std::size_t first = r.out.find("MESSAGE(\"m410 p=2 q=None level=1\")");
  const std::size_t move = r.out.find("STRAIGHT_TRAVERSE(5.0000");
  ASSERT_NE(first, std::string::npos) << r.out;
  EXPECT_LT(first, move);  // group 10 runs before the motion of its block
  EXPECT_NE(r.out.find("MESSAGE(\"m410 p=3 q=4.0 level=1\")"), std::string::npos) << r.out;
}

TEST(InterpPython, AnInterpErrorFromARemapStopsWithTheMessageItSet) {
  const Result r = run("M410 P-1\n(debug, not reached)\nM2\n", kRemapIni,
                       {{"subs.py", "import remap\n"}, {"remap.py", kRemapPy}, {"rm411.ngc", "o<rm411> sub\no<rm411> endsub\n"}});
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("test.ngc:1: M410: P must not be negative"), std::string::npos) << r.err;
  EXPECT_EQ(r.out.find("not reached"), std::string::npos) << r.out;
}

TEST(InterpPython, APythonPrologSetsTheBodysParametersAndTheEpilogSeesTheBodysResult) {
  const Result r = run("M411 P21\nM2\n", kRemapIni,
                       {{"subs.py", "import remap\n"},
                        {"remap.py", kRemapPy},
                        {"rm411.ngc", "o<rm411> sub\n(debug, body twice=#<twice>)\n#<result> = [#<twice> + 1]\no<rm411> endsub\n"}});
  ASSERT_TRUE(r.ok) << r.err << r.out;
  EXPECT_NE(r.out.find("MESSAGE(\" body twice=42.000000\")"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("MESSAGE(\"epilog sees 43\")"), std::string::npos) << r.out;
}

TEST(InterpPython, ARemapNamingAMissingPythonFunctionStopsTheStartNamingTheRemapLine) {
  const Result r = run("M2\n",
                       "[RS274NGC]\nREMAP = M410 modalgroup=10 py=nothere\n[PYTHON]\nPATH_PREPEND = .\nTOPLEVEL = subs.py\n",
                       {{"subs.py", "import remap\n"}, {"remap.py", "def other(self, **words):\n    pass\n"}});
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("test.ini:2: REMAP M410: nothere is no function of the Python module `remap`"), std::string::npos)
      << r.err;
}

TEST(InterpPython, APyRemapWithoutAPythonSectionIsRefusedNamingTheLine) {
  const Result r = run("M2\n", "[RS274NGC]\nREMAP = M410 modalgroup=10 py=m410\n", {});
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("a Python remap procedure needs [PYTHON]"), std::string::npos) << r.err;
}

TEST(InterpPython, CanonErrorFromPythonIsACanonicalCall) {
  const Result r = run(";py,import emccanon\n;py,emccanon.CANON_ERROR('spindle not at speed')\nM2\n", kIni,
                       {{"subs.py", "\n"}});
  ASSERT_TRUE(r.ok) << r.err << r.out;
  EXPECT_NE(r.out.find("CANON_ERROR(spindle not at speed)"), std::string::npos) << r.out;
}

TEST(InterpPython, NamedparamsFunctionsArePredefinedReadOnlyParameters) {
  const std::vector<std::pair<std::string, std::string>> files = {
      {"subs.py", "import namedparams\n"},
      {"namedparams.py",
       "def _twice_x(self, *args):\n    return self.params['_x'] * 2\n"
       "def _botched(self, *args):\n    return 'badly botched'\n"}};
  Result r = run(";py,from interpreter import *\nG0 X3\n;py,assert this.current_x == 3 and this.current_y == 0\nG0 Y#<_twice_x>\n;py,assert this.sub_context[0].named_params['_twice_x'].attr == 35\n"
                 ";py,assert this.params['_twice_x'] == 6\nM2\n",
                 kIni, files);
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_NE(r.out.find("STRAIGHT_TRAVERSE(3.0000, 6.0000, 0.0000"), std::string::npos) << r.out;
  r = run("#<_twice_x> = 1\nM2\n", kIni, files);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("Cannot assign to read-only parameter #<_twice_x>"), std::string::npos) << r.err;
  r = run("G0 X#<_botched>\nM2\n", kIni, files);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("#<_botched>: badly botched"), std::string::npos) << r.err;
}

TEST(InterpPython, AnOwordFunctionRunsOneCallLevelDownWithItsOwnLocalsAndSeesItsBlock) {
  const std::vector<std::pair<std::string, std::string>> files = {
      {"subs.py", "import oword\n"},
      {"oword.py",
       "def look(self, *args):\n"
       "    b = self.blocks[0]\n"
       "    print('level', self.call_level, 'block', b.o_name, list(b.params), b.g_modes[0])\n"
       "    self.params['mine'] = 1.0\n"
       "    print('locals', self.params.locals(), len(self.sub_context))\n"
       "    print('top', 'top' in self.params.globals(), '_x' in self.params.globals())\n"}};
  const Result r = run(";py,from interpreter import *\n#<top> = 5\no<look> call [1] [2]\n;py,assert 'mine' not in this.params.locals()\nM2\n", kIni, files);
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_NE(r.out.find("level 1 block look [1.0, 2.0] -1\nlocals ['mine'] 2\ntop True True\n"), std::string::npos) << r.out;
}

// ---------------------------------------------------------------- generators and self.execute()

namespace {

// A machine that stopped where the test says: after a synch the
// interpreter reads this position (program coordinates).
class StoppedMachine : public cnc::interp::RecordingCanon {
 public:
  cnc::Pose at{};
  bool moved_to_at = false;  // current_position() answers `at` (else the commanded end)
  cnc::Pose current_position() const override { return moved_to_at ? at : RecordingCanon::current_position(); }
};

// An interpreter on test.ini/test.ngc of `dir` with the Python host,
// driven read by read by the test (as the task controller drives it).
struct Driven {
  cnc::testing::TempDir dir;
  cnc::ini::IniFile ini;
  StoppedMachine canon;
  std::unique_ptr<cnc::interp::Interpreter> interp;
  fs::path back = fs::current_path();

  Driven(const std::string& program, const std::string& ini_text,
         const std::vector<std::pair<std::string, std::string>>& files) {
    for (const auto& [name, text] : files) dir.write(name, text);
    dir.write("test.ngc", program);
    ini = cnc::ini::IniFile::load(dir.write("test.ini", ini_text));
    fs::current_path(dir.path());
    cnc::interp::Config cfg = cnc::interp::Config::from_ini(ini);
    cfg.default_units = cnc::interp::Units::Mm;
    cfg.linuxcnc_comments = false;
    cfg.script = cnc::interp::make_python_host(cnc::interp::python_settings(ini));
    interp = std::make_unique<cnc::interp::Interpreter>(canon, cfg);
    interp->init();
    interp->open("test.ngc");
  }
  ~Driven() { fs::current_path(back); }
  Driven(const Driven&) = delete;
  Driven& operator=(const Driven&) = delete;

  // read() then execute() of one block (reading past Yield); the status of execute().
  cnc::interp::Status step() {
    cnc::interp::Status rs = interp->read();
    while (rs == cnc::interp::Status::Yield) rs = interp->read();
    if (rs != cnc::interp::Status::Ok) return rs;
    return interp->execute();
  }
  std::string calls() const { return canon.text(); }
};

const char* kGenIni =
    "[RS274NGC]\nSUBROUTINE_PATH = .\n"
    "REMAP = M420 modalgroup=10 py=m420\n"
    "REMAP = M421 modalgroup=10 argspec=P prolog=pro421 ngc=rm421 epilog=epi421\n"
    "REMAP = M430 modalgroup=10 py=m430\n"
    "REMAP = M431 modalgroup=10 argspec=P ngc=rm431\n"
    "REMAP = M432 modalgroup=10 py=m432\n"
    "[PYTHON]\nPATH_PREPEND = .\nTOPLEVEL = subs.py\n";
const char* kGenPy =
    "import emccanon\nfrom interpreter import *\n"
    "def m420(self, **words):\n"
    "    self.execute('G0 Y1')\n"
    "    yield INTERP_EXECUTE_FINISH\n"
    "    emccanon.MESSAGE('after first wait y=%.2f' % self.current_y)\n"
    "    self.execute('G0 Y2')\n"
    "    yield INTERP_EXECUTE_FINISH\n"
    "    emccanon.MESSAGE('after second wait y=%.2f' % self.current_y)\n"
    "    yield INTERP_OK\n"
    "    emccanon.MESSAGE('never: a generator ends at its first other value')\n"
    "def pro421(self, **words):\n"
    "    self.execute('G0 Z5')\n"
    "    yield INTERP_EXECUTE_FINISH\n"
    "    self.params['twice'] = words['p'] * 2\n"
    "    emccanon.MESSAGE('prolog resumed level=%d' % self.remap_level)\n"
    "def epi421(self, **words):\n"
    "    emccanon.MESSAGE('epilog before wait sees %g' % self.params['result'])\n"
    "    yield INTERP_EXECUTE_FINISH\n"
    "    emccanon.MESSAGE('epilog resumed')\n"
    "def m430(self, **words):\n"
    "    emccanon.MESSAGE('m430 level=%d' % self.remap_level)\n"
    "    self.execute('M431 P7')\n"
    "    emccanon.MESSAGE('m430 back level=%d got=%g' % (self.remap_level, self.params['_got']))\n"
    "    self.execute('G0 X#<_got>')\n"
    "    try:\n"
    "        self.execute('G2 X1')\n"
    "    except InterpreterException as e:\n"
    "        emccanon.MESSAGE('caught: ' + e.error_message)\n"
    "def m432(self, **words):\n"
    "    self.execute('M420')\n";
const char* kRm421 = "o<rm421> sub\n(debug, body twice=#<twice>)\n#<result> = [#<twice> + 1]\no<rm421> endsub\n";
const char* kRm431 =
    "o<rm431> sub\n"
    ";py,import interpreter\n"
    ";py,b = interpreter.this.blocks\n"
    ";py,print('blocks', len(b), b[1].m_modes[10], b[2].m_modes[10])\n"
    "(debug, rm431 p=#<p> level=#<_remap_level>)\n#<_got> = [#<p> * 3]\no<rm431> endsub\n";

std::vector<std::pair<std::string, std::string>> gen_files() {
  return {{"subs.py", "import remap\n"}, {"remap.py", kGenPy}, {"rm421.ngc", kRm421}, {"rm431.ngc", kRm431}};
}

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

}  // namespace

TEST(InterpPythonGenerator, ABodyThatYieldsExecuteFinishStopsTheBlockUntilTheMachineCaughtUpThenResumes) {
  using cnc::interp::Status;
  Driven d("M420 G0 X3\nM2\n", kGenIni, gen_files());
  // The body runs to its first yield: the move is made, the block waits.
  ASSERT_EQ(d.step(), Status::ExecuteFinish) << d.calls();
  EXPECT_NE(d.calls().find("STRAIGHT_TRAVERSE(0.0000, 1.0000"), std::string::npos) << d.calls();
  EXPECT_EQ(d.calls().find("after first wait"), std::string::npos) << d.calls();
  // Nothing is read or resumed before the machine caught up.
  EXPECT_EQ(d.interp->read(), Status::SynchRequired);
  // The machine stopped short (say, a feed hold moved it elsewhere): the
  // resumed body sees what synch() read, not what was commanded.
  d.canon.moved_to_at = true;
  d.canon.at[1] = 0.75;
  d.interp->synch();
  ASSERT_EQ(d.step(), Status::ExecuteFinish) << d.calls();
  EXPECT_NE(d.calls().find("MESSAGE(\"after first wait y=0.75\")"), std::string::npos) << d.calls();
  EXPECT_EQ(d.calls().find("after second wait"), std::string::npos) << d.calls();
  d.canon.moved_to_at = false;
  d.interp->synch();
  // The body ends (yield INTERP_OK) and the rest of the block runs: the G0 X3.
  ASSERT_EQ(d.step(), Status::Ok) << d.calls();
  EXPECT_NE(d.calls().find("MESSAGE(\"after second wait y=2.00\")"), std::string::npos) << d.calls();
  EXPECT_EQ(d.calls().find("never"), std::string::npos) << d.calls();
  const std::string c = d.calls();
  EXPECT_LT(c.find("after second wait"), c.find("STRAIGHT_TRAVERSE(3.0000, 2.0000"));
  EXPECT_EQ(d.step(), Status::ProgramEnd);
  EXPECT_EQ(d.interp->remap_level(), 0);
}

TEST(InterpPythonGenerator, APrologAndAnEpilogThatYieldWaitAroundTheNgcBodyAndKeepItsParameters) {
  using cnc::interp::Status;
  Driven d("M421 P21\n(debug, after)\nM2\n", kGenIni, gen_files());
  ASSERT_EQ(d.step(), Status::ExecuteFinish) << d.calls();  // the prolog waits after its move
  EXPECT_NE(d.calls().find("STRAIGHT_TRAVERSE(0.0000, 0.0000, 5.0000"), std::string::npos) << d.calls();
  EXPECT_EQ(d.calls().find("body twice"), std::string::npos) << d.calls();
  EXPECT_EQ(d.interp->remap_level(), 1);
  d.interp->synch();
  // resumed: it sets the body's local, then the body is called
  EXPECT_EQ(d.step(), Status::Ok) << d.calls();
  EXPECT_NE(d.calls().find("MESSAGE(\"prolog resumed level=1\")"), std::string::npos) << d.calls();
  Status st = Status::Ok;
  int waits = 0;
  while ((st = d.step()) != Status::ProgramEnd) {
    ASSERT_TRUE(st == Status::Ok || st == Status::ExecuteFinish) << cnc::interp::to_string(st);
    if (st == Status::ExecuteFinish) {
      ++waits;
      // the epilog waits at the endsub: the body ran, the line after the call did not
      EXPECT_NE(d.calls().find("MESSAGE(\"epilog before wait sees 43\")"), std::string::npos) << d.calls();
      EXPECT_EQ(d.calls().find("epilog resumed"), std::string::npos) << d.calls();
      EXPECT_EQ(d.calls().find(" after"), std::string::npos) << d.calls();
      d.interp->synch();
    }
  }
  EXPECT_EQ(waits, 1);
  const std::string c = d.calls();
  EXPECT_NE(c.find("MESSAGE(\" body twice=42.000000\")"), std::string::npos) << c;
  EXPECT_LT(c.find("epilog resumed"), c.find("MESSAGE(\" after\")")) << c;
}

TEST(InterpPythonGenerator, SelfExecuteRunsALineThatReentersARemapAndSeesTheRemapBlocks) {
  const Result r = run("M430\n(debug, level after=#<_remap_level>)\nM2\n", kGenIni, gen_files());
  ASSERT_TRUE(r.ok) << r.err << r.out;
  const std::string& o = r.out;
  // M431 runs its NGC procedure from inside M430's Python body: two remap
  // levels, the blocks of both on the remap stack (M430 outermost)
  EXPECT_NE(o.find("MESSAGE(\"m430 level=1\")"), std::string::npos) << o;
  EXPECT_NE(o.find("blocks 3 430 431"), std::string::npos) << o;
  EXPECT_NE(o.find("MESSAGE(\" rm431 p=7.000000 level=2.000000\")"), std::string::npos) << o;
  EXPECT_NE(o.find("MESSAGE(\"m430 back level=1 got=21\")"), std::string::npos) << o;
  EXPECT_NE(o.find("STRAIGHT_TRAVERSE(21.0000"), std::string::npos) << o;
  // an error of a line raises InterpreterException; the body goes on
  EXPECT_NE(o.find("MESSAGE(\"caught: "), std::string::npos) << o;
  EXPECT_NE(o.find("MESSAGE(\" level after=0.000000\")"), std::string::npos) << o;
}

TEST(InterpPythonGenerator, AnExceptionAfterAResumeStopsTheProgramNamingTheLineAndThePythonFileLine) {
  const Result r = run("G0 X1\nM420\n(debug, not reached)\nM2\n",
                       "[RS274NGC]\nREMAP = M420 modalgroup=10 py=m420\n[PYTHON]\nPATH_PREPEND = .\nTOPLEVEL = subs.py\n",
                       {{"subs.py", "import remap\n"},
                        {"remap.py", "from interpreter import *\ndef m420(self, **words):\n    self.execute('G0 Y1')\n"
                                     "    yield INTERP_EXECUTE_FINISH\n    y = 0\n    return 1 / y\n"}});
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("test.ngc:2: ZeroDivisionError: division by zero (at "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("remap.py:6)"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("STRAIGHT_TRAVERSE(1.0000, 1.0000"), std::string::npos) << r.out;  // it ran to the yield
  EXPECT_EQ(r.out.find("not reached"), std::string::npos) << r.out;
}

TEST(InterpPythonGenerator, AProcedureThatWaitsCannotRunInsideSelfExecuteAndTheErrorSaysWhy) {
  const Result r = run("M432\nM2\n", kGenIni, gen_files());
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("test.ngc:1: InterpreterException: M420: m420 waits for the machine (yield "
                       "INTERP_EXECUTE_FINISH) inside self.execute()"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("remap.py:"), std::string::npos) << r.err;
}

TEST(InterpPythonGenerator, AnAbortWhileAStageWaitsForgetsItAndTheNextRunStartsAfresh) {
  using cnc::interp::Status;
  Driven d("M420\nM2\n", kGenIni, gen_files());
  ASSERT_EQ(d.step(), Status::ExecuteFinish);
  EXPECT_EQ(d.interp->remap_level(), 1);
  d.interp->reset();  // an abort while the machine moved
  EXPECT_EQ(d.interp->remap_level(), 0);
  d.interp->open("test.ngc");
  EXPECT_EQ(d.interp->read(), Status::Ok);  // a fresh block, no stale resume
  EXPECT_EQ(d.interp->execute(), Status::ExecuteFinish);
  EXPECT_EQ(count(d.calls(), "STRAIGHT_TRAVERSE(0.0000, 1.0000"), 2u) << d.calls();
}

TEST(InterpPythonGenerator, AnOwordFunctionsLineThatNeedsTheMachineStopsReadingUntilTheSynch) {
  using cnc::interp::Status;
  Driven d("o<probe> call\n#<z> = #5063\n(debug, z=#<z>)\nM2\n", kGenIni,
           {{"subs.py", "import remap\nimport oword\n"},
            {"remap.py", kGenPy},
            {"oword.py", "def probe(self):\n    return float(self.execute('G38.2 Z-1 F100'))\n"}});
  // The function's probe needs the machine: read() stops after the call
  // (the assignment reading #5063, 0 before the synch, is not read yet) and
  // waits for the synch.
  EXPECT_EQ(d.interp->read(), Status::Yield);
  EXPECT_NE(d.calls().find("STRAIGHT_PROBE"), std::string::npos) << d.calls();
  EXPECT_EQ(d.interp->read(), Status::SynchRequired);
  d.interp->synch();
  EXPECT_EQ(d.step(), Status::Ok);
  EXPECT_NE(d.calls().find("MESSAGE(\" z=-1.000000\")"), std::string::npos) << d.calls();
}
