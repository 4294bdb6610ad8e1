# Installation and Debian packages (docs/install.md). Five packages, one
# CPack component each:
#   cnc          the controller: cncd, cnc, halcmd, the bus tools, cnc-rs274,
#                cnc-config, cnc-can-up, the systemd unit; the simulators'
#                processes in /usr/lib/<triplet>/cnc; cncd gets its
#                capabilities in postinst
#   cnc-screen   the Qt operator screen (cnc-hmi)
#   cnc-comp     the compensation tool cnc-comp and the commissioning
#                program cnc-commission (their fitting needs Ceres and
#                OpenCV, which the controller does not)
#   cnc-configs  the sample configurations (/usr/share/cnc/configs) and the
#                documentation (/usr/share/doc/cnc-configs)
#   cnc-connectivity  the Python module cnc, the MTConnect agent and the
#                MQTT bridge (docs/connectivity.md), when they are built
# The libraries are static (cnc_library), so nothing of ours is a shared
# library: dpkg-shlibdeps finds the Debian runtime packages of each program.
# scripts/package.sh builds them in one command.

# Where installed programs look for the sample configurations and helpers
# (cnc-config reads these from its own text, set at install time).
set(CNC_CONFIGS_INSTALL_DIR ${CMAKE_INSTALL_DATADIR}/cnc/configs)
set(CNC_HELPERS_INSTALL_DIR ${CMAKE_INSTALL_LIBDIR}/cnc)

# cnc_install_program(<target> <component> <summary>): the program in
# /usr/bin and its manual page, written from its --help text at build time.
set(CNC_MAN_DIR ${CMAKE_BINARY_DIR}/man)
file(MAKE_DIRECTORY ${CNC_MAN_DIR})
add_custom_target(cnc_man_pages ALL)
function(cnc_man_page name component summary)
  set(page ${CNC_MAN_DIR}/${name}.1.gz)
  add_custom_command(OUTPUT ${page}
    COMMAND ${PROJECT_SOURCE_DIR}/scripts/man_from_help.sh ${name} "${summary}" ${page} ${ARGN}
    DEPENDS ${PROJECT_SOURCE_DIR}/scripts/man_from_help.sh ${ARGN}
    COMMENT "Manual page ${name}(1)" VERBATIM)
  add_custom_target(cnc_man_${name} DEPENDS ${page})
  add_dependencies(cnc_man_pages cnc_man_${name})
  install(FILES ${page} DESTINATION ${CMAKE_INSTALL_MANDIR}/man1 COMPONENT ${component})
endfunction()
function(cnc_install_program target component summary)
  if(NOT TARGET ${target})
    return()
  endif()
  install(TARGETS ${target} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT ${component})
  add_custom_command(OUTPUT ${CNC_MAN_DIR}/${target}.1.gz
    COMMAND ${PROJECT_SOURCE_DIR}/scripts/man_from_help.sh ${target} "${summary}" ${CNC_MAN_DIR}/${target}.1.gz
            $<TARGET_FILE:${target}>
    DEPENDS ${PROJECT_SOURCE_DIR}/scripts/man_from_help.sh ${target}
    COMMENT "Manual page ${target}(1)" VERBATIM)
  add_custom_target(cnc_man_${target} DEPENDS ${CNC_MAN_DIR}/${target}.1.gz)
  add_dependencies(cnc_man_pages cnc_man_${target})
  install(FILES ${CNC_MAN_DIR}/${target}.1.gz DESTINATION ${CMAKE_INSTALL_MANDIR}/man1 COMPONENT ${component})
endfunction()

cnc_install_program(cncd controller "the CNC controller daemon")
cnc_install_program(cnc controller "command-line client of the CNC controller")
cnc_install_program(halcmd controller "HAL commands to a running CNC controller")
cnc_install_program(cnc-scope controller "captures HAL pins of a running CNC controller to CSV")
cnc_install_program(cnc-rs274 controller "RS274/NGC interpreter: a program's canonical moves")
cnc_install_program(cnc-estimate controller "a program's motion time from the trajectory planner, offline")
cnc_install_program(cnc-canopen controller "CANopen bus tool: plans, SDO, NMT, EDS")
cnc_install_program(cnc-ethercat controller "EtherCAT bus tool: scan, ESI, plans")
cnc_install_program(cnc-comp comp "screw and error compensation: measurement and fitting")
cnc_install_program(cnc-vision comp "camera measurement: glass scales, calibration, fiducials")
cnc_install_program(cnc-mtconnect connectivity "MTConnect agent of the CNC controller")
cnc_install_program(cnc-mqtt connectivity "MQTT bridge of the CNC controller")
cnc_install_program(cnc-hmi screen "the Qt operator screen of the CNC controller")
cnc_install_program(cnc-commission-wizard screen "the Qt commissioning wizard of the CNC controller")
cnc_install_program(cnc-commission comp "commissioning: bus scan, axes, scaling, direction test, configuration")

# Scripts: the configuration picker and the CAN interface helper, copied
# beside the programs in build/bin too; build/share/cnc/configs points at
# configs/ so that build/bin/cnc-config finds the samples as the installed
# one finds /usr/share/cnc/configs (beside /usr/bin).
foreach(script cnc-config cnc-can-up)
  configure_file(${PROJECT_SOURCE_DIR}/scripts/${script} ${CMAKE_BINARY_DIR}/bin/${script} COPYONLY)
  install(PROGRAMS ${PROJECT_SOURCE_DIR}/scripts/${script} DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT controller)
endforeach()
file(MAKE_DIRECTORY ${CMAKE_BINARY_DIR}/share/cnc)
file(CREATE_LINK ${PROJECT_SOURCE_DIR}/configs ${CMAKE_BINARY_DIR}/share/cnc/configs SYMBOLIC)
cnc_man_page(cnc-config controller "pick, copy and start a CNC machine configuration" ${CMAKE_BINARY_DIR}/bin/cnc-config)
cnc_man_page(cnc-can-up controller "bring a CAN interface up at a configuration's bitrate"
             ${PROJECT_SOURCE_DIR}/scripts/cnc-can-up)

# The optional systemd unit (docs/install.md, "Starting at boot").
install(FILES ${PROJECT_SOURCE_DIR}/cmake/deb/cnc@.service DESTINATION lib/systemd/system COMPONENT controller)

# The simulators' own processes: not commands of the product, helpers for
# trying a configuration without hardware (docs/install.md).
foreach(helper cnc-cia402-sim ecat-sim cnc-modbus-sim cnc-canopen-node)
  if(TARGET ${helper})
    install(TARGETS ${helper} RUNTIME DESTINATION ${CNC_HELPERS_INSTALL_DIR} COMPONENT controller)
  endif()
endforeach()

# The sample configurations, each as a folder; the documentation.
file(GLOB sample_dirs LIST_DIRECTORIES true ${PROJECT_SOURCE_DIR}/configs/*)
foreach(dir IN LISTS sample_dirs)
  if(IS_DIRECTORY ${dir})
    install(DIRECTORY ${dir} DESTINATION ${CNC_CONFIGS_INSTALL_DIR} COMPONENT configs
            PATTERN "*.var" EXCLUDE PATTERN "*.bak" EXCLUDE)
  endif()
endforeach()
install(FILES ${PROJECT_SOURCE_DIR}/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR}-configs COMPONENT configs)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR}-configs/docs COMPONENT configs
        FILES_MATCHING PATTERN "*.md")

# Debian's files in each package's /usr/share/doc/<package>: copyright and
# a changelog (gzip -9n, as Debian policy asks).
set(CNC_DEB_PACKAGES cnc cnc-screen cnc-comp cnc-configs cnc-connectivity)
set(CNC_DEB_COMPONENTS controller screen comp configs connectivity)
string(TIMESTAMP CNC_DEB_DATE "%a, %d %b %Y %H:%M:%S +0000" UTC)
set(changelog ${CMAKE_BINARY_DIR}/deb/changelog)
file(WRITE ${changelog}
  "cnc (${PROJECT_VERSION}) unstable; urgency=low\n\n"
  "  * Built from the project's tree (scripts/package.sh).\n\n"
  " -- cnc maintainers <cnc-maintainers@example.org>  ${CNC_DEB_DATE}\n")
add_custom_command(OUTPUT ${CMAKE_BINARY_DIR}/deb/changelog.gz
  COMMAND gzip -9n -c ${changelog} > ${CMAKE_BINARY_DIR}/deb/changelog.gz
  DEPENDS ${changelog} VERBATIM)
add_custom_target(cnc_deb_changelog ALL DEPENDS ${CMAKE_BINARY_DIR}/deb/changelog.gz)
foreach(pkg comp IN ZIP_LISTS CNC_DEB_PACKAGES CNC_DEB_COMPONENTS)
  install(FILES ${PROJECT_SOURCE_DIR}/cmake/deb/copyright ${CMAKE_BINARY_DIR}/deb/changelog.gz
          DESTINATION ${CMAKE_INSTALL_DATADIR}/doc/${pkg} COMPONENT ${comp})
endforeach()

# --- CPack: one Debian package per component.
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME cnc)
set(CPACK_PACKAGE_VENDOR "cnc")
set(CPACK_PACKAGE_CONTACT "cnc maintainers <cnc-maintainers@example.org>")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES TRUE)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL controller screen comp configs)
if(TARGET cnc-mtconnect OR TARGET cnc-mqtt OR TARGET cnc_python)
  list(APPEND CPACK_COMPONENTS_ALL connectivity)
endif()
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_SECTION electronics)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION TRUE)
set(CPACK_DEBIAN_PACKAGE_GENERATE_SHLIBS OFF)

set(CPACK_DEBIAN_CONTROLLER_PACKAGE_NAME cnc)
set(CPACK_DEBIAN_CONTROLLER_PACKAGE_DEPENDS "libcap2-bin, passwd")
set(CPACK_DEBIAN_CONTROLLER_PACKAGE_RECOMMENDS "cnc-configs, iproute2")
set(CPACK_DEBIAN_CONTROLLER_PACKAGE_SUGGESTS "cnc-screen")
set(CPACK_DEBIAN_CONTROLLER_PACKAGE_CONTROL_EXTRA ${PROJECT_SOURCE_DIR}/cmake/deb/postinst)
set(CPACK_COMPONENT_CONTROLLER_DESCRIPTION
  "fieldbus-first CNC controller: daemon, clients and tools\n"
  "A CNC controller after LinuxCNC's architecture whose axes are CiA 402\n"
  "drives on CANopen or EtherCAT. This package has the controller daemon\n"
  "cncd, the command-line client cnc, halcmd, the bus tools, the G-code\n"
  "interpreter tool, the configuration picker cnc-config and the CAN\n"
  "helper cnc-can-up.")

set(CPACK_DEBIAN_SCREEN_PACKAGE_NAME cnc-screen)
set(CPACK_DEBIAN_SCREEN_PACKAGE_DEPENDS "cnc (= ${PROJECT_VERSION})")
# The commissioning wizard runs cnc-commission's steps.
set(CPACK_DEBIAN_SCREEN_PACKAGE_RECOMMENDS "cnc-comp (= ${PROJECT_VERSION})")
set(CPACK_COMPONENT_SCREEN_DESCRIPTION
  "fieldbus-first CNC controller: the operator screen\n"
  "The Qt operator screen (cnc-hmi) of the cnc controller: positions,\n"
  "jogging, MDI, programs with a preview, tools, offsets and alarms; and\n"
  "the commissioning wizard (cnc-commission-wizard).")

set(CPACK_DEBIAN_COMP_PACKAGE_NAME cnc-comp)
set(CPACK_DEBIAN_COMP_PACKAGE_DEPENDS "cnc (= ${PROJECT_VERSION})")
set(CPACK_COMPONENT_COMP_DESCRIPTION
  "fieldbus-first CNC controller: the compensation tool\n"
  "cnc-comp measures a machine's positioning errors (ISO 230-2 cycles, a\n"
  "laser or camera measurement) and fits screw, backlash and error\n"
  "compensation tables for the controller's compensation components;\n"
  "cnc-vision reads glass scales and fiducials with a camera;\n"
  "cnc-commission commissions a machine's drives step by step (bus scan,\n"
  "axes, scaling, switches, homing, tuning, compensation, configuration).")

set(CPACK_DEBIAN_CONFIGS_PACKAGE_NAME cnc-configs)
set(CPACK_DEBIAN_CONFIGS_PACKAGE_ARCHITECTURE all)
set(CPACK_DEBIAN_CONFIGS_PACKAGE_SHLIBDEPS OFF)
set(CPACK_COMPONENT_CONFIGS_DESCRIPTION
  "fieldbus-first CNC controller: sample configurations and documentation\n"
  "Machine configurations to start from (a simulated mill, CANopen and\n"
  "EtherCAT mills, a gantry, an inch machine, Modbus spindles), copied to\n"
  "~/cnc/configs by cnc-config, and the controller's documentation.")

set(CPACK_DEBIAN_CONNECTIVITY_PACKAGE_NAME cnc-connectivity)
set(CPACK_DEBIAN_CONNECTIVITY_PACKAGE_DEPENDS "cnc (= ${PROJECT_VERSION}), python3")
set(CPACK_COMPONENT_CONNECTIVITY_DESCRIPTION
  "fieldbus-first CNC controller: Python, MTConnect and MQTT\n"
  "The Python module cnc (shaped like LinuxCNC's linuxcnc module), the\n"
  "MTConnect agent cnc-mtconnect and the MQTT bridge cnc-mqtt; all listen\n"
  "on 127.0.0.1 and are read-only unless configured otherwise.")

include(CPack)
