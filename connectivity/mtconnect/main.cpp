// cnc-mtconnect: an MTConnect agent (version 1.3) for a running controller
// (docs/connectivity.md). It reads the shared segment as any client does
// and never sends a command: the controller is never affected by it or by
// its HTTP clients. HTTP from cpp-httplib; binds 127.0.0.1 unless told.
#include <httplib.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "connectivity/mtconnect/agent.hpp"
#include "core/ipc/client.hpp"
#include "core/util/strings.hpp"
#include "core/util/time.hpp"

using namespace cnc;

namespace {

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

[[noreturn]] void usage(const std::string& msg) {
  std::fprintf(stderr,
               "cnc-mtconnect: %s\n"
               "usage: cnc-mtconnect [-i INSTANCE] [--host ADDRESS] [--port N] [--rate HZ] [--buffer N]\n"
               "                     [--device NAME] [--uuid UUID]\n"
               "  --host    address to listen on (default 127.0.0.1; 0.0.0.0: every interface)\n"
               "  --port    TCP port (default 5000; 0: any free port, printed at start)\n"
               "  --rate    status samples per second (default 10)\n"
               "  --buffer  observations kept for /sample (default 4096)\n",
               msg.c_str());
  std::exit(2);
}

int64_t int_arg(const std::string& s, const char* what, int64_t lo, int64_t hi) {
  const auto v = parse_int(s);
  if (!v || *v < lo || *v > hi) {
    usage(std::string(what) + ": \"" + s + "\" is not an integer from " + std::to_string(lo) + " to " +
          std::to_string(hi));
  }
  return *v;
}

}  // namespace

int main(int argc, char** argv) {
  std::string instance = ipc::default_instance();
  std::string host = "127.0.0.1";
  int port = 5000;
  double rate = 10;
  mtconnect::AgentOptions opt;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has = i + 1 < argc;
    if ((a == "-i" || a == "--instance") && has) instance = argv[++i];
    else if (a == "--host" && has) host = argv[++i];
    else if (a == "--port" && has) port = static_cast<int>(int_arg(argv[++i], "port", 0, 65535));
    else if (a == "--rate" && has) rate = static_cast<double>(int_arg(argv[++i], "rate", 1, 1000));
    else if (a == "--buffer" && has) opt.buffer_size = static_cast<std::size_t>(int_arg(argv[++i], "buffer", 16, 1 << 22));
    else if (a == "--device" && has) opt.device_name = argv[++i];
    else if (a == "--uuid" && has) opt.uuid = argv[++i];
    else if (a == "--help" || a == "-h") usage("an MTConnect agent for the controller");
    else usage("unknown argument \"" + a + "\"");
  }

  // The model's axes: those of the controller when it runs now, else X Y Z.
  std::unique_ptr<ipc::Client> client;
  try {
    client = std::make_unique<ipc::Client>(instance);
    const uint32_t mask = client->status().motion.axis_mask;
    if (mask) opt.axis_mask = mask;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cnc-mtconnect: %s: serving UNAVAILABLE until it starts\n", e.what());
    client.reset();
  }
  mtconnect::Agent agent(opt);
  std::mutex mutex;

  httplib::Server server;
  auto reply = [&](httplib::Response& res, const std::string& body, int status = 200) {
    res.status = status;
    res.set_content(body, "application/xml");
  };
  server.Get("/probe", [&](const httplib::Request&, httplib::Response& res) {
    std::lock_guard lock(mutex);
    reply(res, agent.probe(realtime_ns()));
  });
  server.Get("/current", [&](const httplib::Request&, httplib::Response& res) {
    std::lock_guard lock(mutex);
    reply(res, agent.current(realtime_ns()));
  });
  server.Get("/sample", [&](const httplib::Request& req, httplib::Response& res) {
    std::lock_guard lock(mutex);
    uint64_t from = 0, count = 100;
    for (const char* key : {"from", "count"}) {
      if (!req.has_param(key)) continue;
      const auto v = parse_int(req.get_param_value(key));
      if (!v || *v < 0) {
        return reply(res, agent.error("INVALID_REQUEST", std::string("'") + key + "' must be a non-negative integer",
                                      realtime_ns()), 400);
      }
      (std::string(key) == "from" ? from : count) = static_cast<uint64_t>(*v);
    }
    int status = 200;
    const std::string body = agent.sample(from, count, realtime_ns(), status);
    reply(res, body, status);
  });
  server.Get("/assets", [&](const httplib::Request&, httplib::Response& res) {
    std::lock_guard lock(mutex);
    reply(res, agent.assets(realtime_ns()));
  });
  server.set_error_handler([&](const httplib::Request& req, httplib::Response& res) {
    if (res.status != 404) return;
    std::lock_guard lock(mutex);
    reply(res, agent.error("UNSUPPORTED", "no such request: " + req.path, realtime_ns()), 404);
  });

  const int bound = port == 0 ? server.bind_to_any_port(host) : (server.bind_to_port(host, port) ? port : -1);
  if (bound < 0) {
    std::fprintf(stderr, "cnc-mtconnect: cannot listen on %s:%d\n", host.c_str(), port);
    return 1;
  }
  std::printf("cnc-mtconnect: listening on http://%s:%d/ (MTConnect %s)\n", host.c_str(), bound, mtconnect::kVersion);
  std::fflush(stdout);
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::thread http([&] { server.listen_after_bind(); });

  // Sampling: the status at `rate`, every message; when the controller goes
  // away everything is UNAVAILABLE and the agent reconnects with back-off.
  const auto period = std::chrono::microseconds(static_cast<int64_t>(1e6 / rate));
  auto backoff = std::chrono::milliseconds(250);
  auto next_try = std::chrono::steady_clock::now();
  while (!g_stop) {
    if (!client && std::chrono::steady_clock::now() >= next_try) {
      try {
        // Messages posted from now on: older ones were seen before the
        // controller went away, or belong to its previous run.
        client = std::make_unique<ipc::Client>(instance);
        backoff = std::chrono::milliseconds(250);
        std::fprintf(stderr, "cnc-mtconnect: connected to the controller (instance \"%s\")\n", instance.c_str());
      } catch (const std::exception&) {
        next_try = std::chrono::steady_clock::now() + backoff;
        backoff = std::min(backoff * 2, std::chrono::milliseconds(5000));
      }
    }
    if (client) {
      try {
        const ipc::Status s = client->status();
        std::lock_guard lock(mutex);
        Message m;
        while (client->next_message(m)) agent.message(m, m.time_ns);
        agent.update(&s, realtime_ns());
        if (!client->controller_alive()) throw ipc::ClientError("controller stopped");
      } catch (const std::exception& e) {
        std::fprintf(stderr, "cnc-mtconnect: %s: UNAVAILABLE until it is back\n", e.what());
        client.reset();
        std::lock_guard lock(mutex);
        agent.update(nullptr, realtime_ns());
        next_try = std::chrono::steady_clock::now() + backoff;
      }
    }
    std::this_thread::sleep_for(period);
  }
  server.stop();
  http.join();
  return 0;
}
