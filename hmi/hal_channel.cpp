#include "hmi/hal_channel.hpp"

#include <chrono>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <thread>

namespace cnc::hmi {

HalExecutor make_admin_executor(const std::string& instance) {
  auto client = std::make_shared<std::unique_ptr<ipc::AdminClient>>();
  return [client, instance](const std::string& line) -> ipc::AdminReply {
    try {
      if (!*client) *client = std::make_unique<ipc::AdminClient>(instance);
      return (*client)->request(line);
    } catch (...) {
      client->reset();  // next request connects again
      throw;
    }
  };
}

struct HalChannel::Shared {
  std::mutex mutex;
  std::condition_variable wake;
  std::condition_variable finished_cv;
  std::deque<std::pair<int, std::string>> queue;
  std::string poll_pattern;
  int poll_ms = 0;
  bool stop = false;
  bool finished = false;
  HalExecutor executor;
  HalChannel* owner = nullptr;  // null once the channel is gone
};

HalChannel::HalChannel(HalExecutor executor, QObject* parent) : QObject(parent), shared_(std::make_shared<Shared>()) {
  shared_->executor = std::move(executor);
  shared_->owner = this;
  std::thread([s = shared_]() {
    std::string last_poll;
    auto next_poll = std::chrono::steady_clock::now();
    std::unique_lock lock(s->mutex);
    while (!s->stop) {
      if (!s->queue.empty()) {
        const auto [tag, line] = s->queue.front();
        s->queue.pop_front();
        lock.unlock();
        bool ok = false;
        std::string text;
        try {
          const ipc::AdminReply r = s->executor(line);
          ok = r.ok;
          text = r.text;
        } catch (const std::exception& e) {
          text = e.what();
        }
        lock.lock();
        if (s->owner) {
          emit s->owner->replied(tag, QString::fromStdString(line), ok, QString::fromStdString(text));
        }
        continue;
      }
      if (s->poll_ms > 0 && std::chrono::steady_clock::now() >= next_poll) {
        const std::string line = "show pin " + s->poll_pattern;
        next_poll = std::chrono::steady_clock::now() + std::chrono::milliseconds(s->poll_ms);
        lock.unlock();
        std::string text;
        try {
          const ipc::AdminReply r = s->executor(line);
          if (r.ok) text = r.text;
        } catch (const std::exception&) {
        }
        lock.lock();
        if (!text.empty() && text != last_poll && s->owner) {
          last_poll = text;
          emit s->owner->polled(QString::fromStdString(text));
        }
        continue;
      }
      if (s->poll_ms > 0) s->wake.wait_until(lock, next_poll);
      else s->wake.wait(lock);
    }
    s->finished = true;
    s->finished_cv.notify_all();
  }).detach();
}

HalChannel::~HalChannel() {
  std::unique_lock lock(shared_->mutex);
  shared_->owner = nullptr;
  shared_->stop = true;
  shared_->wake.notify_all();
  // A request stuck on a hung controller must not hang the screen's exit:
  // wait a moment, then leave the thread to finish on its own.
  shared_->finished_cv.wait_for(lock, std::chrono::seconds(1), [&] { return shared_->finished; });
}

void HalChannel::request(const QString& line, int tag) {
  std::lock_guard lock(shared_->mutex);
  shared_->queue.emplace_back(tag, line.toStdString());
  shared_->wake.notify_all();
}

void HalChannel::set_poll(const QString& pattern, int period_ms) {
  std::lock_guard lock(shared_->mutex);
  shared_->poll_pattern = pattern.toStdString();
  shared_->poll_ms = period_ms;
  shared_->wake.notify_all();
}

}  // namespace cnc::hmi
