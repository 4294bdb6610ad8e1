// Reading lines from the program and subroutine files, and O-word control
// flow: sub/endsub/call/return, if/elseif/else/endif, while, do/while,
// repeat, break, continue.
#include <cmath>
#include <cstring>

#include "core/interp/impl.hpp"

namespace cnc::interp {

namespace {
uint32_t bit(OType t) { return 1u << static_cast<unsigned>(t); }

bool is_percent_line(std::string_view raw) {
  std::size_t i = 0;
  while (i < raw.size() && (raw[i] == ' ' || raw[i] == '\t')) ++i;
  return i < raw.size() && raw[i] == '%';
}
}  // namespace

void Interpreter::State::open_file(const std::string& path) {
  SourceFile f;
  try {
    f.reader = std::make_unique<LineReader>(path);
  } catch (const InterpError& e) {
    // LinuxCNC's wording, and why (missing, a FIFO, a directory, ...).
    fail("Unable to open file <" + path + ">: " + e.message());
  }
  f.path = path;
  push_source(std::move(f));
}

void Interpreter::State::push_source(SourceFile f) {
  f.id = next_source_id++;
  files.push_back(std::move(f));
}

// Loops and skips never outlive the source they started in.
void Interpreter::State::pop_source() {
  const int id = files.back().id;
  for (Frame& fr : frames) {
    std::erase_if(fr.loops, [id](const Loop& l) { return l.source == id; });
  }
  files.pop_back();
  skipping = false;
  skip_defining = false;
}

void Interpreter::State::jump(int64_t offset, int line_before) { files.back().reader->seek(offset, line_before); }

bool Interpreter::State::next_raw_line(std::string_view& text) {
  for (;;) {
    if (files.empty()) return false;
    SourceFile& f = files.back();
    line_offset = f.reader->offset();
    if (f.reader->next(text)) {
      current_line = f.reader->line_number();
      current_file = f.path;
      return true;
    }
    return false;
  }
}

void Interpreter::State::start_skip(const std::string& label, std::initializer_list<OType> types, bool defining) {
  skipping = true;
  skip_label = label;
  skip_types = 0;
  for (OType t : types) skip_types |= bit(t);
  skip_defining = defining;
}

bool Interpreter::State::skip_line_matches(std::string_view raw) {
  // Cheap test first: an O-word line starts (after blanks, '/', N word) with o.
  std::size_t i = 0;
  auto blank = [&] {
    while (i < raw.size() && (raw[i] == ' ' || raw[i] == '\t')) ++i;
  };
  blank();
  if (i < raw.size() && raw[i] == '/') ++i;
  blank();
  if (i < raw.size() && (raw[i] == 'n' || raw[i] == 'N')) {
    ++i;
    while (i < raw.size() && (std::strchr("0123456789. \t", raw[i]) != nullptr)) ++i;
  }
  if (i >= raw.size() || (raw[i] != 'o' && raw[i] != 'O')) return false;
  parse_line(raw);
  if (block.o_type == OType::None || block.o_name != skip_label) {
    if (skip_defining && block.o_type == OType::Sub) fail("Nested subroutine definition");
    return false;
  }
  return (skip_types & bit(block.o_type)) != 0;
}

std::optional<std::string> Interpreter::State::find_sub_file(const std::string& name) const {
  std::vector<std::filesystem::path> dirs = config.subroutine_path;
  if (!program_path.empty()) dirs.push_back(std::filesystem::path(program_path).parent_path());
  dirs.push_back(".");
  for (const auto& d : dirs) {
    for (const std::string& n : {name + ".ngc", name + ".NGC"}) {
      const auto p = d.empty() ? std::filesystem::path(n) : d / n;
      // Whatever exists under the name is taken: a FIFO or a folder there
      // is refused by open_file() with the reason, not silently passed over.
      std::error_code ec;
      if (std::filesystem::exists(p, ec)) return p.string();
    }
  }
  return std::nullopt;
}

void Interpreter::State::count_line() {
  ++lines_this_read;
  const uint64_t outputs = queueing.outputs();
  if (outputs != outputs_seen) {
    outputs_seen = outputs;
    lines_without_output = 0;
  }
  if (++lines_without_output > config.max_blocks_without_output) {
    const std::string n = std::to_string(config.max_blocks_without_output);
    fail(n + " blocks in a row without machine output (motion, dwell, spindle, coolant, tool, output or input "
             "wait): an endless loop? ([RS274NGC]MAX_BLOCKS_WITHOUT_OUTPUT = " + n + ")");
  }
}

ReadResult Interpreter::State::read_block() {
  std::string_view raw;
  for (;;) {
    // Back to the caller between two lines once this call has read its
    // share; everything needed to go on is in the state.
    if (lines_this_read >= config.lines_per_read) return ReadResult::Yield;
    if (!next_raw_line(raw)) {
      if (files.empty()) return ReadResult::End;
      if (files.size() > 1 && files.back().path == "<mdi>") {
        pop_source();
        return ReadResult::End;
      }
      if (skipping) {
        line_text.clear();
        if (skip_types & bit(OType::Sub)) fail("Failed to find sub 'O" + skip_label + "' before EOF");
        fail("File ended with no percent sign");
      }
      if (files.back().path == "<mdi>") {
        pop_source();
        return ReadResult::End;
      }
      if (frames.size() > 1) fail("File ended with no percent sign or program end");
      fail(percent_seen ? "File ended with no percent sign" : "File ended with no percent sign or program end");
    }
    line_text.assign(raw);
    count_line();
    const bool at_top = files.size() == 1 && files.back().path != "<mdi>";
    if (first_line && at_top) {
      first_line = false;
      if (is_percent_line(raw)) {
        percent_seen = true;
        continue;
      }
    } else if (percent_seen && at_top && !skipping && is_percent_line(raw)) {
      program_ended = true;
      canon.begin_block(current_line, -1, {});
      canon.finish();
      return ReadResult::End;
    }
    if (skipping) {
      if (!skip_line_matches(raw)) continue;
      skipping = false;
      const OType t = block.o_type;
      // Ends of structures are consumed; else/elseif are evaluated.
      if (t != OType::ElseIf && t != OType::Else) {
        if (t == OType::EndSub && skip_defining) skip_defining = false;
        continue;
      }
    } else {
      parse_line(raw);
    }
    if (block.o_type != OType::None) {
      handle_o_word();
      // A G7x cycle reading its contour: the subroutine returned.
      if (capture_depth >= 0 && static_cast<int>(frames.size()) <= capture_depth) return ReadResult::End;
      if (resume_block) {
        // A remap procedure returned: the rest of its block runs now.
        resume_block = false;
        return ReadResult::Block;
      }
      // A Python epilog to run at the endsub: execute() runs it.
      if (stage.kind != StageKind::None) return ReadResult::Block;
      // A Python O-word function ran a line (self.execute()) that needs the
      // machine to catch up: nothing more is read until then (the next
      // read() says SynchRequired).
      if (synch_pending) return ReadResult::Yield;
      continue;
    }
    // Parameter settings take effect once the whole line is read.
    for (const Assignment& a : block.assigns) {
      if (a.index >= 0) {
        set_param(a.index, a.value, true);
      } else {
        set_named(a.name, a.value);
      }
    }
    if (block.has == 0 && block.m_count == 0 && !block.has_comment && !block.has_py && !block.has_dollar &&
        !block.has_polar_r && !block.has_polar_a) {
      bool any_g = false;
      for (int g : block.g) any_g = any_g || g != -1;
      if (!any_g) continue;
    }
    return ReadResult::Block;
  }
}

namespace {
double eval_o_value(Interpreter::State& s) {
  std::size_t i = s.o_args_pos;
  const double v = s.read_expression(i);
  return v;
}
}  // namespace

// LinuxCNC: a label that opens if/while/repeat must not open another
// structure at a different line (of the same file and subroutine).
void Interpreter::State::check_label_unique(const std::string& label) {
  std::string key = files.back().path;
  key += '\x1f';
  key += frame().sub_name;
  key += '\x1f';
  key += label;
  const auto [it, inserted] = o_label_lines.emplace(std::move(key), current_line);
  if (inserted || it->second == current_line) return;
  std::string src = line_text;
  while (!src.empty() && (src.front() == ' ' || src.front() == '\t')) src.erase(0, 1);
  const std::string here = std::to_string(current_line);
  const std::string there = std::to_string(it->second);
  if (block.o_type == OType::If) {
    fail(here + ": duplicate O-word label - already defined in line " + there + ": '" + src + "'");
  }
  fail(here + ": duplicate O-word label: '" + src + "' - defined in line " + there);
}

bool Interpreter::State::handle_o_word() {
  const std::string label = block.o_name;
  Frame& fr = frame();
  const int src = files.back().id;
  auto top_is = [&](LoopKind k) {
    return !fr.loops.empty() && fr.loops.back().label == label && fr.loops.back().kind == k && fr.loops.back().source == src;
  };
  auto top_label = [&] { return !fr.loops.empty() && fr.loops.back().label == label && fr.loops.back().source == src; };
  switch (block.o_type) {
    case OType::Sub: {
      SubDef d{files.back().path, files.back().reader->offset(), current_line};
      if (const auto it = subs.find(label); it != subs.end() && (it->second.file != d.file || it->second.line != d.line)) {
        auto shown = [&](const std::string& f) { return f == program_path ? program_display_name : f; };
        fail("File:" + shown(d.file) + " line:" + std::to_string(current_line) + " redefining sub: o|" + label +
             "| already defined in file:" + shown(it->second.file));
      }
      subs[label] = d;
      start_skip(label, {OType::EndSub}, true);
      return true;
    }
    case OType::EndSub:
    case OType::Return: {
      bool has_value = false;
      double value = 0;
      std::size_t i = o_args_pos;
      while (i < norm.size() && norm[i] == '(') read_comment(i);
      if (i < norm.size() && norm[i] == '[') {
        value = read_expression(i);
        has_value = true;
      }
      if (frames.size() > 1 && frame().fanuc) fail("Fanuc 'O....' subroutine definition must end with 'M99'");
      if (frames.size() <= 1) {
        std::string src = line_text;
        while (!src.empty() && (src.front() == ' ' || src.front() == '\t')) src.erase(0, 1);
        fail(std::to_string(current_line) + ": not in a subroutine definition: '" + src + "'");
      }
      do_return(has_value, value);
      return true;
    }
    case OType::Call: {
      std::vector<double> args;
      std::size_t i = o_args_pos;
      while (i < norm.size()) {
        if (norm[i] == '[') {
          args.push_back(read_expression(i));
        } else if (norm[i] == '(') {
          read_comment(i);
        } else {
          fail("Unexpected character after O-word");
        }
      }
      if (args.size() > 30) fail("Too many subroutine parameters");
      block.call_args = std::move(args);
      do_call();
      return true;
    }
    case OType::If: {
      check_label_unique(label);
      const bool cond = eval_o_value(*this) != 0.0;
      fr.if_done[label] = cond;
      if (!cond) start_skip(label, {OType::ElseIf, OType::Else, OType::EndIf});
      return true;
    }
    case OType::ElseIf: {
      auto it = fr.if_done.find(label);
      if (it != fr.if_done.end() && it->second) {
        start_skip(label, {OType::EndIf});
        return true;
      }
      const bool cond = eval_o_value(*this) != 0.0;
      fr.if_done[label] = cond;
      if (!cond) start_skip(label, {OType::ElseIf, OType::Else, OType::EndIf});
      return true;
    }
    case OType::Else: {
      auto it = fr.if_done.find(label);
      if (it != fr.if_done.end() && it->second) {
        start_skip(label, {OType::EndIf});
        return true;
      }
      fr.if_done[label] = true;
      return true;
    }
    case OType::EndIf:
      fr.if_done.erase(label);
      return true;
    case OType::Do: {
      Loop l{label, LoopKind::Do, line_offset, current_line, files.back().reader->offset(), current_line, 0, files.back().id};
      fr.loops.push_back(l);
      return true;
    }
    case OType::While: {
      if (top_is(LoopKind::Do)) {
        const bool cond = eval_o_value(*this) != 0.0;
        if (cond) {
          jump(fr.loops.back().body_offset, fr.loops.back().body_line);
        } else {
          fr.loops.pop_back();
        }
        return true;
      }
      check_label_unique(label);
      const bool again = top_is(LoopKind::While) && fr.loops.back().offset == line_offset;
      const bool cond = eval_o_value(*this) != 0.0;
      if (cond) {
        if (!again) {
          fr.loops.push_back(
              Loop{label, LoopKind::While, line_offset, current_line, files.back().reader->offset(), current_line, 0,
                   files.back().id});
        }
      } else {
        if (again) fr.loops.pop_back();
        start_skip(label, {OType::EndWhile});
      }
      return true;
    }
    case OType::EndWhile: {
      if (!top_label()) fail("Unknown oword number");
      jump(fr.loops.back().offset, fr.loops.back().line - 1);
      return true;
    }
    case OType::Repeat: {
      check_label_unique(label);
      const double v = eval_o_value(*this);
      const int count = round_to_int((v));
      if (count <= 0) {
        start_skip(label, {OType::EndRepeat});
        return true;
      }
      fr.loops.push_back(
          Loop{label, LoopKind::Repeat, line_offset, current_line, files.back().reader->offset(), current_line, count,
               files.back().id});
      return true;
    }
    case OType::EndRepeat: {
      if (!top_label()) fail("Unknown oword number");
      Loop& l = fr.loops.back();
      if (--l.remaining > 0) {
        jump(l.body_offset, l.body_line);
      } else {
        fr.loops.pop_back();
      }
      return true;
    }
    case OType::Break:
    case OType::Continue: {
      if (!top_label()) fail("Unknown oword number");
      Loop l = fr.loops.back();
      if (block.o_type == OType::Break) {
        fr.loops.pop_back();
        if (l.kind == LoopKind::While) start_skip(label, {OType::EndWhile});
        if (l.kind == LoopKind::Repeat) start_skip(label, {OType::EndRepeat});
        if (l.kind == LoopKind::Do) start_skip(label, {OType::While});
        return true;
      }
      if (l.kind == LoopKind::While) {
        jump(l.offset, l.line - 1);
      } else if (l.kind == LoopKind::Do) {
        jump(l.body_offset, l.body_line);
      } else {
        Loop& top = fr.loops.back();
        if (--top.remaining > 0) {
          jump(top.body_offset, top.body_line);
        } else {
          fr.loops.pop_back();
          start_skip(label, {OType::EndRepeat});
        }
      }
      return true;
    }
    case OType::FanucSub:
      // Reached in the flow of the program: a program title, or the start
      // of a Fanuc subprogram the program runs into; nothing to do.
      return true;
    case OType::None:
      break;
  }
  return false;
}

void Interpreter::State::do_call(bool fanuc, int repeats) {
  const std::string label = block.o_name;
  const std::vector<double> args = block.call_args;
  if (frames.size() >= 64) fail("Too many subroutine levels");
  if (!fanuc && config.script && config.script->has_oword(label)) {
    // a script function: called at once, no frame; its number (if any) is
    // the call's value as a G-code sub's return value is
    std::optional<double> value;
    // The function runs one call level down, as LinuxCNC's: what it sets in
    // self.params by a local name is its own local.
    Frame f;
    f.sub_name = label;
    f.file_depth = static_cast<int>(files.size());
    frames.push_back(std::move(f));
    try {
      value = config.script->call_oword(label, args);
    } catch (const std::runtime_error& e) {
      frames.pop_back();
      fail("o<" + label + "> (Python): " + e.what());
    }
    frames.pop_back();
    globals["_value"] = value ? *value : 0.0;
    globals["_value_returned"] = value ? 1.0 : 0.0;
    return;
  }
  auto it = subs.find(label);
  if (it == subs.end()) {
    // Look further down this file, then in a file named after the sub.
    LineReader& r = *files.back().reader;
    bool hit_percent = false;
    const int64_t back_offset = r.offset();
    const int back_line = r.line_number();
    const std::string saved_text = line_text;
    const int saved_line = current_line;
    std::string_view raw;
    bool found = false;
    std::string last_text = saved_text;
    if (files.back().path != "<mdi>") {
      const bool main_program = files.size() == 1 && percent_seen;
      while (r.next(raw)) {
        last_text.assign(raw);
        current_line = r.line_number();
        if (main_program && is_percent_line(raw)) {
          // Nothing after the closing '%' belongs to the program.
          hit_percent = true;
          break;
        }
        if (skip_line_matches_sub(raw, label)) {
          subs[label] = SubDef{files.back().path, r.offset(), r.line_number(), block.o_type == OType::FanucSub,
                               std::string(raw)};
          found = true;
          break;
        }
      }
      r.seek(back_offset, back_line);
    }
    current_line = saved_line;
    line_text = saved_text;
    if (!found) {
      const auto path = find_sub_file(label);
      if (!path && hit_percent) {
        // LinuxCNC reads the closing '%' (FINISH) and gives up.
        line_text = last_text;
        canon.finish();
        fail("Failed to find sub 'O" + label + "' before EOF");
      }
      if (!path) {
        // LinuxCNC's wording: it searched to the end of the file.
        line_text = last_text;
        std::string shown = files.back().path;
        if (!program_path.empty() && shown == program_path) shown = program_display_name;
        fail("EOF in file:" + shown + " seeking o-word: o<" + label + "> from line: " + std::to_string(saved_line));
      }
      std::unique_ptr<LineReader> opened;
      try {
        opened = std::make_unique<LineReader>(*path);
      } catch (const InterpError& e) {
        fail("Unable to open file <" + *path + ">: " + e.message());
      }
      LineReader& fr = *opened;
      while (fr.next(raw)) {
        if (skip_line_matches_sub(raw, label)) {
          subs[label] = SubDef{*path, fr.offset(), fr.line_number(), block.o_type == OType::FanucSub, std::string(raw)};
          found = true;
          break;
        }
      }
      if (!found) fail("Failed to find sub 'O" + label + "' before EOF");
    }
    it = subs.find(label);
  }
  if (it->second.fanuc != fanuc) {
    // LinuxCNC keeps the two styles apart; the error shows the definition.
    line_text = it->second.text;
    fail(fanuc ? "'O.... sub' subroutine must be called with 'O.... call'"
               : "Fanuc 'O....' subroutine must be called with 'M98'");
  }
  Frame f;
  f.sub_name = label;
  f.fanuc = fanuc;
  f.fanuc_repeats = repeats - 1;
  f.fanuc_def = it->second;
  // An M98 subprogram shares #1-#30 with its caller (Fanuc).
  for (int k = 0; k < 30 && !fanuc; ++k) {
    f.saved_args[static_cast<std::size_t>(k)] = params[static_cast<std::size_t>(k + 1)];
    params[static_cast<std::size_t>(k + 1)] =
        k < static_cast<int>(args.size()) ? args[static_cast<std::size_t>(k)] : 0.0;
  }
  f.file_depth = static_cast<int>(files.size());
  f.return_offset = files.back().reader->offset();
  f.return_line = files.back().reader->line_number();
  if (config.oword_nargs) f.locals["n_args"] = static_cast<double>(args.size());
  const SubDef def = it->second;
  frames.push_back(std::move(f));
  if (def.file != files.back().path) {
    open_file(def.file);
  }
  jump(def.offset, def.line);
}

bool Interpreter::State::skip_line_matches_sub(std::string_view raw, const std::string& label) {
  std::size_t i = 0;
  while (i < raw.size() && (raw[i] == ' ' || raw[i] == '\t')) ++i;
  if (i >= raw.size() || (raw[i] != 'o' && raw[i] != 'O')) return false;
  parse_line(raw);
  return (block.o_type == OType::Sub || block.o_type == OType::FanucSub) && block.o_name == label;
}

void Interpreter::State::do_return(bool has_value, double value) {
  if (const auto& rc = frames.back().remap; rc && rc->stage == 1 && rc->spec->epilog_python && !rc->epilog_done) {
    // A Python epilog runs before the body's call is left: it sees the
    // body's local parameters (as in LinuxCNC). It runs in execute() (it
    // may wait for the machine): read() hands the endsub over as the block,
    // and the return is made when the epilog ended (run_stage).
    rc->epilog_done = true;
    stage = {StageKind::Epilog, false, rc, has_value, value};
    return;
  }
  Frame f = std::move(frames.back());
  frames.pop_back();
  if (!f.fanuc) {
    for (int k = 0; k < 30; ++k) params[static_cast<std::size_t>(k + 1)] = f.saved_args[static_cast<std::size_t>(k)];
    globals["_value"] = has_value ? value : 0.0;
    globals["_value_returned"] = has_value ? 1.0 : 0.0;
  }
  if (f.restore_on_return && f.saved_modal.valid) restore_modal(f.saved_modal);
  while (static_cast<int>(files.size()) > f.file_depth) pop_source();
  jump(f.return_offset, f.return_line);
  if (f.remap) remap_returned(f.remap);
}

}  // namespace cnc::interp
