// The camera cycle's Positioner on a running controller: each move is one
// MDI line "G53 G1 <axis><target> F<feed>" (machine coordinates), then the
// positioner waits until the interpreter is idle, the MDI queue and the
// motion queue are empty and motion is in position; settling is a wait.
// The machine must be on, homed and in MDI mode. A controller that stops,
// an MDI line that is rejected, an E-stop or machine-off, an error during
// the move or a move that does not end within `timeout_s` end the move
// with the reason. Offline (a client of the shared segment).
#pragma once

#include <string>

#include "comp/camera_cycle.hpp"
#include "core/ipc/client.hpp"

namespace cnc::comp {

class IpcPositioner : public Positioner {
 public:
  IpcPositioner(ipc::Client& client, char axis, double feed_mm_min, double timeout_s = 120)
      : c_(client), axis_(axis), feed_(feed_mm_min), timeout_s_(timeout_s) {}
  std::string move_to(double target_mm) override;
  void settle(double seconds) override;

 private:
  ipc::Client& c_;
  char axis_;
  double feed_;
  double timeout_s_;
};

}  // namespace cnc::comp
