#include "core/hal/scope.hpp"

#include <algorithm>
#include <cstdio>

#include "core/util/strings.hpp"

namespace cnc::hal {

ScopeCapture::ScopeCapture(std::size_t capacity, int channels)
    : buffer_(capacity * kMaxChannels, 0.0), capacity_(capacity), channels_(channels), samples_(capacity) {}

void ScopeCapture::configure(int channels, std::size_t samples, int pre_percent, int trigger_channel, ScopeEdge edge,
                             double level, ScopeMode mode) {
  const State s = state();
  if (s != State::Idle && s != State::Done) throw HalError("scope: stop the capture before changing it");
  if (channels < 1 || channels > kMaxChannels) throw HalError("scope: 1 to 16 channels");
  if (samples < 2 || samples > capacity_) {
    throw HalError("scope: samples=" + std::to_string(samples) + ": 2 to " + std::to_string(capacity_) +
                   " (loadrt scope samples=N sizes the buffer)");
  }
  if (pre_percent < 0 || pre_percent > 100) throw HalError("scope: pre= is a percentage, 0 to 100");
  if (trigger_channel < 0 || trigger_channel >= channels) throw HalError("scope: no such trigger channel");
  channels_ = channels;
  samples_ = samples;
  pre_ = std::min(samples - 1, samples * static_cast<std::size_t>(pre_percent) / 100);
  trigger_channel_ = trigger_channel;
  edge_ = edge;
  level_ = level;
  mode_ = mode;
  state_.store(State::Idle, std::memory_order_release);
}

void ScopeCapture::arm() noexcept {
  written_ = 0;
  trigger_at_ = 0;
  waited_ = 0;
  previous_ = 0;
  forced_ = false;
  state_.store(State::Filling, std::memory_order_release);
}

void ScopeCapture::stop() noexcept { state_.store(State::Idle, std::memory_order_release); }

void ScopeCapture::push(const double* values) noexcept {
  State s = state_.load(std::memory_order_acquire);
  if (s == State::Idle || s == State::Done) return;
  if (s == State::Filling && written_ >= pre_) {
    s = State::Waiting;
    state_.store(s, std::memory_order_release);
  }
  double* row = &buffer_[(written_ % samples_) * kMaxChannels];
  for (int c = 0; c < channels_; ++c) row[c] = values[c];
  const double v = values[trigger_channel_];
  const double prev = written_ == 0 ? v : previous_;
  previous_ = v;
  ++written_;
  if (s == State::Waiting) {
    bool fire = false;
    switch (edge_) {
      case ScopeEdge::Rising: fire = prev < level_ && v >= level_; break;
      case ScopeEdge::Falling: fire = prev > level_ && v <= level_; break;
      case ScopeEdge::Level: fire = v >= level_; break;
      case ScopeEdge::None: fire = true; break;
    }
    if (!fire && mode_ == ScopeMode::Auto && ++waited_ >= samples_) {
      fire = true;
      forced_ = true;
    }
    if (fire) {
      trigger_at_ = written_ - 1;
      s = State::Post;
      state_.store(s, std::memory_order_release);
    }
  }
  if (s == State::Post && written_ - trigger_at_ >= samples_ - pre_) state_.store(State::Done, std::memory_order_release);
}

std::vector<std::vector<double>> ScopeCapture::rows() const {
  if (state() != State::Done) throw HalError("scope: no finished capture");
  std::vector<std::vector<double>> out;
  out.reserve(samples_);
  const std::size_t start = written_ - samples_;
  for (std::size_t i = 0; i < samples_; ++i) {
    const double* row = &buffer_[((start + i) % samples_) * kMaxChannels];
    out.emplace_back(row, row + channels_);
  }
  return out;
}

namespace {
const char* state_name(ScopeCapture::State s) {
  switch (s) {
    case ScopeCapture::State::Idle: return "idle";
    case ScopeCapture::State::Filling: return "filling";
    case ScopeCapture::State::Waiting: return "waiting";
    case ScopeCapture::State::Post: return "triggered";
    case ScopeCapture::State::Done: return "done";
  }
  return "?";
}

double as_double(Type t, uint64_t bits) noexcept {
  switch (t) {
    case Type::Bit: return bits ? 1.0 : 0.0;
    case Type::Float: return decode<double>(bits);
    case Type::S32: return decode<int32_t>(bits);
    case Type::U32: return decode<uint32_t>(bits);
    case Type::S64: return static_cast<double>(decode<int64_t>(bits));
    case Type::U64: return static_cast<double>(decode<uint64_t>(bits));
  }
  return 0;
}
}  // namespace

Scope::Scope(ComponentContext& ctx, const LoadArgs& args)
    : Component(ctx.hal, "scope"),
      capture_(static_cast<std::size_t>(args.get_int("samples", 4000, 2, 1'000'000)), 1) {
  args.allow_only({"samples"});
  export_method<&Scope::sample>("scope.sample", this);
}

void Scope::sample(const rt::CycleInfo& info) noexcept {
  const auto s = capture_.state();
  if (s == ScopeCapture::State::Idle || s == ScopeCapture::State::Done) return;
  const int n = active_.load(std::memory_order_acquire);
  if (n == 0) return;
  period_ns_.store(info.period_ns > 0 ? info.period_ns : info.actual_period_ns, std::memory_order_relaxed);
  double values[ScopeCapture::kMaxChannels];
  for (int i = 0; i < n; ++i) values[i] = as_double(types_[i], pins_[i]->cell.load(std::memory_order_relaxed)->raw());
  capture_.push(values);
}

std::string Scope::command(const std::vector<std::string>& w) {
  const std::string sub = w.empty() ? "state" : w[0];
  if (sub == "setup") {
    if (w.size() < 2) throw HalError("scope setup PIN[,PIN...] [trigger=PIN] [edge=rising|falling|level|none] "
                                     "[level=V] [pre=PERCENT] [samples=N] [mode=single|normal|auto]");
    std::vector<std::string> names = split(w[1], ',', true);
    std::string trigger;
    ScopeEdge edge = ScopeEdge::None;
    bool edge_given = false;
    double level = 0.5;
    int pre = 10;
    std::size_t samples = capture_.samples();
    ScopeMode mode = ScopeMode::Single;
    for (std::size_t i = 2; i < w.size(); ++i) {
      const auto eq = w[i].find('=');
      if (eq == std::string::npos) throw HalError("scope setup: \"" + w[i] + "\": expected key=value");
      const std::string k = w[i].substr(0, eq), v = w[i].substr(eq + 1);
      if (k == "trigger") {
        trigger = v;
      } else if (k == "edge") {
        edge_given = true;
        if (v == "rising") edge = ScopeEdge::Rising;
        else if (v == "falling") edge = ScopeEdge::Falling;
        else if (v == "level") edge = ScopeEdge::Level;
        else if (v == "none") edge = ScopeEdge::None;
        else throw HalError("scope setup: edge=" + v + ": expected rising, falling, level or none");
      } else if (k == "level") {
        const auto d = parse_double(v);
        if (!d) throw HalError("scope setup: level=" + v + ": expected a number");
        level = *d;
      } else if (k == "pre") {
        const auto n = parse_int(v);
        if (!n) throw HalError("scope setup: pre=" + v + ": expected a percentage");
        pre = static_cast<int>(*n);
      } else if (k == "samples") {
        const auto n = parse_int(v);
        if (!n || *n < 2) throw HalError("scope setup: samples=" + v + ": expected a count of at least 2");
        samples = static_cast<std::size_t>(*n);
      } else if (k == "mode") {
        if (v == "single") mode = ScopeMode::Single;
        else if (v == "normal") mode = ScopeMode::Normal;
        else if (v == "auto") mode = ScopeMode::Auto;
        else throw HalError("scope setup: mode=" + v + ": expected single, normal or auto");
      } else {
        throw HalError("scope setup: unknown key \"" + k + "\"");
      }
    }
    int trigger_channel = 0;
    if (!trigger.empty()) {
      const auto it = std::find(names.begin(), names.end(), trigger);
      if (it == names.end()) names.push_back(trigger);
      trigger_channel = static_cast<int>(std::find(names.begin(), names.end(), trigger) - names.begin());
      if (!edge_given) edge = ScopeEdge::Rising;
    } else if (edge != ScopeEdge::None) {
      throw HalError("scope setup: edge= needs trigger=PIN");
    }
    if (names.empty() || names.size() > static_cast<std::size_t>(ScopeCapture::kMaxChannels)) {
      throw HalError("scope setup: 1 to 16 pins");
    }
    std::vector<const detail::PinObj*> objs;
    for (const auto& n : names) objs.push_back(hal().find_pin(n));
    const auto st = capture_.state();
    if (st != ScopeCapture::State::Idle && st != ScopeCapture::State::Done) {
      throw HalError("scope: a capture runs (" + std::string(state_name(st)) + "): scope stop first");
    }
    // Nothing samples now: the buffer is Idle or Done.
    active_.store(0, std::memory_order_release);
    capture_.configure(static_cast<int>(names.size()), samples, pre, trigger_channel, edge, level, mode);
    for (std::size_t i = 0; i < objs.size(); ++i) {
      pins_[i] = objs[i];
      types_[i] = objs[i]->type;
    }
    names_ = names;
    active_.store(static_cast<int>(names.size()), std::memory_order_release);
    return {};
  }
  if (sub == "arm") {
    if (names_.empty()) throw HalError("scope arm: scope setup first");
    capture_.arm();
    return {};
  }
  if (sub == "stop") {
    capture_.stop();
    return {};
  }
  if (sub == "state") {
    return std::string(state_name(capture_.state())) + " samples=" + std::to_string(capture_.samples()) +
           " pre=" + std::to_string(capture_.pre_samples()) + " channels=" + std::to_string(names_.size()) +
           (capture_.forced() ? " forced" : "") + "\n";
  }
  if (sub == "csv") return csv();
  throw HalError("scope: unknown subcommand \"" + sub + "\" (setup, arm, stop, state, csv)");
}

std::string Scope::csv() {
  if (capture_.state() != ScopeCapture::State::Done) {
    throw HalError(std::string("scope csv: no finished capture (") + state_name(capture_.state()) + ")");
  }
  const auto rows = capture_.rows();
  std::string out = "time_s";
  for (const auto& n : names_) out += "," + n;
  out += "\n";
  const double period = static_cast<double>(period_ns_.load(std::memory_order_relaxed)) * 1e-9;
  char buf[64];
  for (std::size_t i = 0; i < rows.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%.6f", (static_cast<double>(i) - static_cast<double>(capture_.pre_samples())) * period);
    out += buf;
    for (double v : rows[i]) {
      std::snprintf(buf, sizeof buf, ",%.10g", v);
      out += buf;
    }
    out += "\n";
  }
  // Normal mode: the next trigger is awaited as soon as this one was read.
  if (capture_.mode() == ScopeMode::Normal) capture_.arm();
  return out;
}

}  // namespace cnc::hal
