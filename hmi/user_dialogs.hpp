// User message dialogs driven by HAL pins ([DISPLAY] MESSAGE_* and
// MULTIMESSAGE_*, developer manual chapter 6 "User Message Dialogs"): the
// configuration, the pins the screen creates as a HAL remote component
// (newcomp/newpin over the halcmd channel), and the state machine that turns
// pin values into dialogs and answers into pin writes. No Qt: the widgets
// only show what the actions say.
//
// Pins of component `hmi` (names lower case, '_' becomes '-'):
//   hmi.<pin>            bit io   MESSAGE: TRUE pops the dialog; the screen resets it
//   hmi.<pin>-waiting    bit out  TRUE while the dialog is up
//   hmi.<pin>-response   bit out  yesnodialog: TRUE = yes, FALSE = no
//   hmi.<id>             s32 io   MULTIMESSAGE: the message number, 0 = none
//   hmi.<id>-waiting     bit out
#pragma once

#include <map>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace cnc::ini {
class IniFile;
}

namespace cnc::hmi {

struct UserMessage {
  std::string pin;      // pin word below the component ("bothtest")
  std::string title;    // MESSAGE_BOLDTEXT / MULTIMESSAGE_<ID>_TITLE
  std::string text;
  std::string details;
  std::string icon;     // INFO, WARNING, CRITICAL, QUESTION (free text)
  bool ok = false, yesno = false, none = false, status = false;  // from *_TYPE
  int number = 0;       // MULTIMESSAGE number (0 for MESSAGE_*)
  bool has_dialog() const noexcept { return ok || yesno || none; }
};

struct MultiMessage {
  std::string id;   // as written (VFD)
  std::string pin;  // pin word ("vfd")
  std::vector<UserMessage> messages;
  const UserMessage* find(int number) const;
};

struct UserDialogConfig {
  std::vector<UserMessage> messages;
  std::vector<MultiMessage> multi;
  std::vector<std::string> warnings;
  bool empty() const noexcept { return messages.empty() && multi.empty(); }
  static UserDialogConfig from_ini(const ini::IniFile& ini);
};

// A HAL name word from a user's name: lower case, '_' -> '-'; empty (and
// `why`) when it has other characters than letters, digits, '-' and '.'.
std::string hal_pin_word(std::string_view name, std::string* why = nullptr);

// "show pin <pattern>" output -> pin name -> value text.
std::map<std::string, std::string> parse_show_pin(std::string_view text);

class UserDialogLogic {
 public:
  struct Action {
    enum class Kind { Show, Close, Status, Set, Log } kind;
    const UserMessage* message = nullptr;  // Show, Close, Status
    std::string pin;                       // Set: full pin name
    std::string value;                     // Set: value; Log: text
  };

  UserDialogLogic(UserDialogConfig config, std::string component = "hmi");

  const UserDialogConfig& config() const noexcept { return config_; }
  const std::string& component() const noexcept { return component_; }
  // newcomp and newpin lines, in order.
  std::vector<std::string> setup_commands() const;
  // Pattern for "show pin": every pin of the component.
  std::string poll_pattern() const { return component_ + "."; }

  // New values of the component's pins.
  std::vector<Action> update(const std::map<std::string, std::string>& pins);
  // The operator closed the dialog of `message`: OK / Yes (true) or No.
  std::vector<Action> answer(const UserMessage* message, bool yes);

 private:
  std::string full(const std::string& word) const { return component_ + "." + word; }
  void pop(const UserMessage* m, const std::string& trigger, const std::string& waiting, std::vector<Action>& out);

  UserDialogConfig config_;
  std::string component_;
  std::map<const UserMessage*, bool> shown_;
  std::map<std::string, int> multi_number_;
  std::set<const UserMessage*> awaiting_reset_;  // answered: a stale TRUE is ignored  // last number seen per multimessage id
};

}  // namespace cnc::hmi
