// cnc-mqtt: publishes a running controller's state, positions, program
// events and alarms to an MQTT broker as JSON (docs/connectivity.md), and,
// only when enabled with a token and a whitelist, takes commands. It reads
// the shared segment as any client does: the broker going away never
// affects the controller; libmosquitto reconnects with back-off.
#include <mosquitto.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <deque>
#include <fstream>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "connectivity/mqtt/bridge.hpp"
#include "core/ipc/client.hpp"
#include "core/util/strings.hpp"
#include "core/util/time.hpp"

using namespace cnc;

namespace {

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

[[noreturn]] void usage(const std::string& msg) {
  std::fprintf(stderr,
               "cnc-mqtt: %s\n"
               "usage: cnc-mqtt [-i INSTANCE] [--host BROKER] [--port N] [--prefix TOPIC] [--rate HZ]\n"
               "                [--client-id ID] [--username NAME --password-file FILE]\n"
               "                [--commands --token-file FILE --allow CMD,CMD...]\n"
               "  --host, --port     the broker (default 127.0.0.1:1883)\n"
               "  --prefix           topic prefix (default cnc)\n"
               "  --rate             positions per second (default 5)\n"
               "  --commands         take commands on PREFIX/command (off by default); needs\n"
               "                     --token-file (the secret each command carries) and --allow\n",
               msg.c_str());
  std::exit(2);
}

std::string read_secret(const std::string& path, const char* what) {
  std::ifstream f(path);
  if (!f) usage(std::string(what) + ": cannot read " + path);
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string s(trim(ss.str()));
  if (s.empty()) usage(std::string(what) + ": " + path + " is empty");
  return s;
}

struct Bridge {
  std::string prefix = "cnc";
  std::string token;
  std::set<std::string> allowed;
  bool commands = false;
  std::atomic<bool> connected{false};
  std::mutex mutex;                      // guards inbox
  std::deque<std::string> inbox;         // command payloads, handled in the main loop
  bool need_state = true;                // republish the retained state (after a connect)
};

void on_connect(struct mosquitto* m, void* user, int rc) {
  auto* b = static_cast<Bridge*>(user);
  if (rc != 0) {
    std::fprintf(stderr, "cnc-mqtt: broker refused the connection: %s\n", mosquitto_connack_string(rc));
    return;
  }
  std::fprintf(stderr, "cnc-mqtt: connected to the broker\n");
  const std::string online = "online";
  mosquitto_publish(m, nullptr, (b->prefix + "/availability").c_str(), static_cast<int>(online.size()), online.data(), 1, true);
  if (b->commands) mosquitto_subscribe(m, nullptr, (b->prefix + "/command").c_str(), 1);
  std::lock_guard lock(b->mutex);
  b->need_state = true;
  b->connected = true;
}

void on_disconnect(struct mosquitto*, void* user, int rc) {
  auto* b = static_cast<Bridge*>(user);
  b->connected = false;
  if (rc != 0) std::fprintf(stderr, "cnc-mqtt: lost the broker (%s): reconnecting\n", mosquitto_strerror(rc));
}

void on_message(struct mosquitto*, void* user, const struct mosquitto_message* msg) {
  auto* b = static_cast<Bridge*>(user);
  std::lock_guard lock(b->mutex);
  if (b->inbox.size() < 64) b->inbox.emplace_back(static_cast<const char*>(msg->payload), static_cast<std::size_t>(msg->payloadlen));
}

void publish(struct mosquitto* m, const Bridge& b, const std::string& sub, const std::string& payload, bool retain,
             int qos = 0) {
  if (!b.connected) return;
  mosquitto_publish(m, nullptr, (b.prefix + "/" + sub).c_str(), static_cast<int>(payload.size()), payload.data(), qos,
                    retain);
}

struct Pending {
  uint32_t serial;
  std::string id, name;
  std::chrono::steady_clock::time_point deadline;
};

std::string result_json(const std::string& id, const std::string& name, bool ok, const std::string& reason) {
  nlohmann::json j;
  j["id"] = id;
  j["command"] = name;
  j["ok"] = ok;
  if (!reason.empty()) j["reason"] = reason;
  return j.dump();
}

}  // namespace

int main(int argc, char** argv) {
  std::string instance = ipc::default_instance();
  std::string host = "127.0.0.1", client_id, username, password;
  int port = 1883;
  double rate = 5;
  Bridge b;
  std::string token_file, allow;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has = i + 1 < argc;
    if ((a == "-i" || a == "--instance") && has) instance = argv[++i];
    else if (a == "--host" && has) host = argv[++i];
    else if (a == "--port" && has) {
      const auto v = parse_int(argv[++i]);
      if (!v || *v < 1 || *v > 65535) usage("--port: expected 1 to 65535");
      port = static_cast<int>(*v);
    } else if (a == "--prefix" && has) b.prefix = argv[++i];
    else if (a == "--rate" && has) {
      const auto v = parse_double(argv[++i]);
      if (!v || *v <= 0 || *v > 100) usage("--rate: expected more than 0 and at most 100 per second");
      rate = *v;
    } else if (a == "--client-id" && has) client_id = argv[++i];
    else if (a == "--username" && has) username = argv[++i];
    else if (a == "--password-file" && has) password = read_secret(argv[++i], "--password-file");
    else if (a == "--commands") b.commands = true;
    else if (a == "--token-file" && has) token_file = argv[++i];
    else if (a == "--allow" && has) allow = argv[++i];
    else if (a == "--help" || a == "-h") usage("an MQTT bridge for the controller");
    else usage("unknown argument \"" + a + "\"");
  }
  if (b.prefix.empty() || b.prefix.find_first_of("#+") != std::string::npos) usage("--prefix: a topic without + or #");
  if (b.commands) {
    if (token_file.empty()) usage("--commands needs --token-file");
    if (allow.empty()) usage("--commands needs --allow (the commands it may take)");
    b.token = read_secret(token_file, "--token-file");
    std::stringstream ss(allow);
    for (std::string name; std::getline(ss, name, ',');) {
      name = std::string(trim(name));
      bool known = false;
      for (const auto& n : mqtt::command_names()) known = known || n == name;
      if (!known) usage("--allow: unknown command \"" + name + "\"");
      b.allowed.insert(name);
    }
  } else if (!token_file.empty() || !allow.empty()) {
    usage("--token-file and --allow need --commands");
  }

  mosquitto_lib_init();
  if (client_id.empty()) client_id = "cnc-mqtt-" + instance + "-" + std::to_string(::getpid());
  struct mosquitto* m = mosquitto_new(client_id.c_str(), true, &b);
  if (!m) {
    std::fprintf(stderr, "cnc-mqtt: cannot create the MQTT client\n");
    return 1;
  }
  const std::string offline = "offline";
  mosquitto_will_set(m, (b.prefix + "/availability").c_str(), static_cast<int>(offline.size()), offline.data(), 1, true);
  if (!username.empty()) mosquitto_username_pw_set(m, username.c_str(), password.empty() ? nullptr : password.c_str());
  mosquitto_connect_callback_set(m, on_connect);
  mosquitto_disconnect_callback_set(m, on_disconnect);
  mosquitto_message_callback_set(m, on_message);
  mosquitto_reconnect_delay_set(m, 1, 30, true);  // back-off: 1 s doubling up to 30 s
  if (mosquitto_loop_start(m) != MOSQ_ERR_SUCCESS) {
    std::fprintf(stderr, "cnc-mqtt: cannot start the MQTT thread\n");
    return 1;
  }
  // Asynchronous: a broker that is not there yet is retried by the loop.
  const int crc = mosquitto_connect_async(m, host.c_str(), port, 30);
  if (crc != MOSQ_ERR_SUCCESS) {
    std::fprintf(stderr, "cnc-mqtt: %s:%d: %s (retrying)\n", host.c_str(), port, mosquitto_strerror(crc));
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::fprintf(stderr, "cnc-mqtt: publishing under %s/ to %s:%d%s\n", b.prefix.c_str(), host.c_str(), port,
               b.commands ? " (commands enabled)" : " (read-only)");

  std::unique_ptr<ipc::Client> client;
  std::optional<ipc::Status> last;
  std::string last_state;
  std::deque<Pending> pending;
  auto backoff = std::chrono::milliseconds(250);
  auto next_try = std::chrono::steady_clock::now();
  auto next_position = std::chrono::steady_clock::now();
  const auto position_period = std::chrono::microseconds(static_cast<int64_t>(1e6 / rate));
  while (!g_stop) {
    const auto now = std::chrono::steady_clock::now();
    if (!client && now >= next_try) {
      try {
        client = std::make_unique<ipc::Client>(instance);
        backoff = std::chrono::milliseconds(250);
        std::fprintf(stderr, "cnc-mqtt: connected to the controller (instance \"%s\")\n", instance.c_str());
      } catch (const std::exception&) {
        next_try = now + backoff;
        backoff = std::min(backoff * 2, std::chrono::milliseconds(5000));
      }
    }
    bool republish = false;
    {
      std::lock_guard lock(b.mutex);
      republish = b.need_state;
      b.need_state = false;
    }
    if (client) {
      try {
        const ipc::Status s = client->status();
        const std::string st = mqtt::state_json(s);
        if (st != last_state || republish) publish(m, b, "state", st, true, 1);
        last_state = st;
        for (const auto& e : mqtt::program_events(last ? &*last : nullptr, s)) publish(m, b, "program", e, false, 1);
        if (now >= next_position) {
          publish(m, b, "position", mqtt::position_json(s, s.motion.axis_mask), false);
          next_position = now + position_period;
        }
        Message msg;
        while (client->next_message(msg)) {
          publish(m, b, msg.kind == MessageKind::Error ? "alarm" : "message", mqtt::message_json(msg), false, 1);
        }
        last = s;
        // Commands: checked, sent, their answers published on PREFIX/command/result.
        std::deque<std::string> inbox;
        {
          std::lock_guard lock(b.mutex);
          inbox.swap(b.inbox);
        }
        for (const std::string& payload : inbox) {
          try {
            const mqtt::CommandRequest r = mqtt::parse_command(payload, b.token, b.allowed);
            if (r.estop) client->request_estop();
            pending.push_back({client->send(r.command), r.id, r.name, now + std::chrono::seconds(60)});
          } catch (const std::exception& e) {
            std::string id;
            try {
              const auto j = nlohmann::json::parse(payload);
              if (j.is_object() && j.contains("id")) id = j["id"].is_string() ? j["id"].get<std::string>() : j["id"].dump();
            } catch (const std::exception&) {
            }
            std::fprintf(stderr, "cnc-mqtt: command refused: %s\n", e.what());
            publish(m, b, "command/result", result_json(id, "", false, e.what()), false, 1);
          }
        }
        for (auto it = pending.begin(); it != pending.end();) {
          const ipc::CommandResult r = client->wait(it->serial, std::chrono::milliseconds(0));
          if (r.state == ipc::CommandState::Done || r.state == ipc::CommandState::Rejected || now > it->deadline) {
            const bool ok = r.state == ipc::CommandState::Done;
            publish(m, b, "command/result",
                    result_json(it->id, it->name, ok, ok ? "" : r.state == ipc::CommandState::Rejected ? r.reason.c_str() : "no answer within 60 s"),
                    false, 1);
            it = pending.erase(it);
          } else {
            ++it;
          }
        }
        if (!client->controller_alive()) throw ipc::ClientError("controller stopped");
      } catch (const std::exception& e) {
        std::fprintf(stderr, "cnc-mqtt: %s: waiting for it\n", e.what());
        client.reset();
        last.reset();
        pending.clear();
        last_state = R"({"task_state":"UNAVAILABLE"})";
        publish(m, b, "state", last_state, true, 1);
        next_try = now + backoff;
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  // An orderly end says offline itself (the will is for a crash).
  publish(m, b, "availability", offline, true, 1);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  mosquitto_disconnect(m);
  mosquitto_loop_stop(m, false);
  mosquitto_destroy(m);
  mosquitto_lib_cleanup();
  return 0;
}
