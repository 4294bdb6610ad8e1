// cnc-commission-wizard: the commissioning steps as a Qt wizard over the
// state file of cnc-commission (docs/commissioning.md, "The wizard").
//   cnc-commission-wizard [--state FILE] [--dir CONFIG_DIR] [--instance NAME]
// Each page runs a subcommand of cnc-commission (found beside this program)
// and shows what the state file holds afterwards; the status strip reads
// the controller of the instance (default $CNC_INSTANCE) when one runs.
#include <QApplication>
#include <cstdio>
#include <string>

#include "commission/wizard/wizard_window.hpp"
#include "core/ipc/segment.hpp"
#include "hmi/link.hpp"

int main(int argc, char** argv) {
  QApplication app(argc, argv);
  cnc::commission::wizard::WizardOptions o;
  o.instance = QString::fromStdString(cnc::ipc::default_instance());
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--state" && has_value) o.state_file = argv[++i];
    else if (a == "--dir" && has_value) o.config_dir = argv[++i];
    else if (a == "--instance" && has_value) o.instance = argv[++i];
    else if (a == "--program" && has_value) o.program = argv[++i];
    else {
      std::fprintf(stderr,
                   "usage: cnc-commission-wizard [--state FILE] [--dir CONFIG_DIR] [--instance NAME] [--program "
                   "CNC_COMMISSION]\n");
      return a == "--help" || a == "-h" ? 0 : 2;
    }
  }
  qputenv("CNC_INSTANCE", o.instance.toUtf8());  // the subcommands reach the same controller
  cnc::commission::wizard::WizardWindow w(o, std::make_unique<cnc::hmi::ClientLink>(o.instance.toStdString()));
  w.resize(1200, 860);
  w.show();
  return app.exec();
}
