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

const char* kUsage =
    "usage: cnc-commission-wizard [--state FILE] [--dir CONFIG_DIR] [--instance NAME] [--program PATH]\n"
    "The commissioning steps of cnc-commission as a Qt wizard: one page per step\n"
    "(1 bus scan, 2 axes, 3 scaling, 4 direction test, 5 limits and switches,\n"
    "6 homing, 7 tuning, 8 compensation, 9 write), back/next, the steps done, and\n"
    "a status strip of the running controller (E-stop chain, drives, positions).\n"
    "\n"
    "  --state FILE       the state file of cnc-commission (default commission.json)\n"
    "  --dir CONFIG_DIR   where the configuration is written and brought up\n"
    "                     (default commission-config beside the state file)\n"
    "  --instance NAME    the controller's instance (default $CNC_INSTANCE)\n"
    "  --program PATH     cnc-commission (default: beside this program)\n";

int main(int argc, char** argv) {
  cnc::commission::wizard::WizardOptions o;
  o.instance = QString::fromStdString(cnc::ipc::default_instance());
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--state" && has_value) o.state_file = argv[++i];
    else if (a == "--dir" && has_value) o.config_dir = argv[++i];
    else if (a == "--instance" && has_value) o.instance = argv[++i];
    else if (a == "--program" && has_value) o.program = argv[++i];
    else if (a == "--help" || a == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    } else {
      std::fprintf(stderr, "cnc-commission-wizard: unknown argument %s\n%s", a.c_str(), kUsage);
      return 2;
    }
  }
  QApplication app(argc, argv);
  qputenv("CNC_INSTANCE", o.instance.toUtf8());  // the subcommands reach the same controller
  cnc::commission::wizard::WizardWindow w(o, std::make_unique<cnc::hmi::ClientLink>(o.instance.toStdString()));
  w.resize(1200, 860);
  w.show();
  return app.exec();
}
