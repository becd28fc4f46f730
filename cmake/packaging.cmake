# Installation, the CMake package SweptCCD, the pkg-config file sweptccd.pc
# and the Debian packages (cpack -G DEB). Included at the end of the top
# CMakeLists.txt, after every target exists. Tests: tests/packaging/.
#
#   cmake --install build --prefix /opt/sweptccd     # everything
#   cpack -G DEB --config build/CPackConfig.cmake    # sweptccd_*.deb, sweptccd-dev_*.deb
#
# Two install components:
#   runtime  -> package sweptccd:     the daemon, the sweptccd tool, the systemd
#               unit (lib/systemd/system), the example configuration and the
#               unit's GPU drop-in (share/doc/sweptccd/examples), the Java jar of
#               the message types for lcm-spy (share/java/sweptccd_msgs.jar)
#   dev      -> package sweptccd-dev: the exported static libraries, their headers
#               under include/sweptccd/ (the same paths as in this tree:
#               "msgs/signing.h", "sweptccd/tracker_pose_t.hpp", ...), the CMake
#               package (lib/cmake/SweptCCD) and lib/pkgconfig/sweptccd.pc
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)
# `cmake --install` and cpack install what is built and never build (cpack's
# preinstall step would otherwise build every target, tests included): build
# first (cmake --build build), then install or package.
set(CMAKE_SKIP_INSTALL_ALL_DEPENDENCY ON)

set(SWEPTCCD_INSTALL_INCLUDEDIR ${CMAKE_INSTALL_INCLUDEDIR}/sweptccd)
set(SWEPTCCD_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/SweptCCD)
# Debian names doc folders after the package: share/doc/sweptccd.
set(SWEPTCCD_INSTALL_DOCDIR ${CMAKE_INSTALL_DATAROOTDIR}/doc/sweptccd)

# What an exported target may link besides other exported targets: imported
# targets the installed SweptCCDConfig.cmake can recreate in a consumer, each
# as "TARGET|how|pc" where how is pkg:<VAR>:<module> (pkg-config) or
# cmake:<Package> (find_dependency), and pc the pkg-config module sweptccd.pc
# then requires (empty: none). A target linking anything else stops the
# configuration with a message naming it: add it here.
set(SWEPTCCD_EXPORT_DEPENDENCIES
  "PkgConfig::SODIUM|pkg:SODIUM:libsodium|libsodium"
  "PkgConfig::CRYPTO|pkg:CRYPTO:libcrypto|libcrypto"
  "PkgConfig::LCM|pkg:LCM:lcm|lcm"
  "Threads::Threads|cmake:Threads|"
  "spdlog::spdlog|cmake:spdlog|spdlog"
  "nlohmann_json::nlohmann_json|cmake:nlohmann_json|nlohmann_json"
  "Eigen3::Eigen|cmake:Eigen3|eigen3"
  "CLI11::CLI11|cmake:CLI11|"
  "yaml-cpp|cmake:yaml-cpp|yaml-cpp"
  "ZLIB::ZLIB|cmake:ZLIB|zlib"
  "assimp::assimp|cmake:assimp|assimp")
# sweptccd.pc always requires lcm (the generated headers include
# lcm/lcm_coretypes.h); the modules of what the exported libraries link are
# added (static libraries: private dependencies too).
set(SWEPTCCD_PC_REQUIRES lcm)

set_property(GLOBAL PROPERTY SWEPTCCD_EXPORTED_TARGETS "")

# sweptccd_export_library(TARGET [HEADERS path...])
# Installs library TARGET (component dev) into the export set SweptCCDTargets
# as SweptCCD::<TARGET without its sweptccd_ prefix>, and the HEADERS (paths
# relative to the source root: a file, or a folder for every *.h/*.hpp in
# it, not recursive) under include/sweptccd/ at the same relative path.
# Include folders of the tree (PROJECT_SOURCE_DIR, build folders) become
# build-only; installed consumers get include/sweptccd. Call it in link
# order: a library after the libraries it links (the .pc file's -l order).
function(sweptccd_export_library target)
  cmake_parse_arguments(arg "" "" "HEADERS" ${ARGN})
  if(NOT TARGET ${target})
    message(FATAL_ERROR "sweptccd_export_library: no target ${target}")
  endif()
  foreach(prop INTERFACE_INCLUDE_DIRECTORIES INTERFACE_SYSTEM_INCLUDE_DIRECTORIES)
    get_target_property(dirs ${target} ${prop})
    if(dirs)
      set(wrapped)
      foreach(dir IN LISTS dirs)
        if(dir MATCHES "^\\$<")
          list(APPEND wrapped "${dir}")
        else()
          list(APPEND wrapped "$<BUILD_INTERFACE:${dir}>")
        endif()
      endforeach()
      set_property(TARGET ${target} PROPERTY ${prop} "${wrapped}")
    endif()
  endforeach()
  string(REGEX REPLACE "^sweptccd_" "" export_name ${target})
  set_property(TARGET ${target} PROPERTY EXPORT_NAME ${export_name})
  install(TARGETS ${target} EXPORT SweptCCDTargets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT runtime
          INCLUDES DESTINATION ${SWEPTCCD_INSTALL_INCLUDEDIR})
  foreach(path IN LISTS arg_HEADERS)
    set(abs ${PROJECT_SOURCE_DIR}/${path})
    if(IS_DIRECTORY ${abs})
      file(GLOB headers CONFIGURE_DEPENDS ${abs}/*.h ${abs}/*.hpp)
      set(dest ${path})
    elseif(EXISTS ${abs})
      set(headers ${abs})
      get_filename_component(dest ${path} DIRECTORY)
    else()
      message(FATAL_ERROR "sweptccd_export_library(${target}): no header ${path}")
    endif()
    install(FILES ${headers} DESTINATION ${SWEPTCCD_INSTALL_INCLUDEDIR}/${dest} COMPONENT dev)
  endforeach()
  set_property(GLOBAL APPEND PROPERTY SWEPTCCD_EXPORTED_TARGETS ${target})
endfunction()

# --- The exported libraries: one line each, in link order. -----------------
# core/errors.h (InputError, what the signing functions throw), the
# bounded file reader and the typed indices (core/avatar/link_key.h).
sweptccd_export_library(sweptccd_errors HEADERS core/errors.h core/bounded_file.h
                                                core/typed_index.h)
# The message library: checked decoding, signing and keys, the id rule and
# escaping, channel names; its generated headers are installed below.
sweptccd_export_library(sweptccd_msgs HEADERS msgs)
# What the client library's headers need: skeletons and poses (core/avatar),
# with the geometry they are made of.
sweptccd_export_library(sweptccd_geometry HEADERS core/geometry)
sweptccd_export_library(sweptccd_avatar HEADERS core/avatar)
# The client library (client/): LiveClient and DaemonConnection. Its headers
# install under include/sweptccd/sweptccd_client/, so a consumer writes
# #include "sweptccd_client/live_client.h" in the tree and installed alike.
sweptccd_export_library(sweptccd_client)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/client/include/sweptccd_client
        DESTINATION ${SWEPTCCD_INSTALL_INCLUDEDIR} COMPONENT dev
        FILES_MATCHING PATTERN "*.h")
# A new library joins with one sweptccd_export_library line here, after the
# libraries it links (if it links a package not in
# SWEPTCCD_EXPORT_DEPENDENCIES, the configuration says which; add it there):
# its headers, the config file's find_dependency lines and sweptccd.pc's
# Libs and Requires follow from the line and the target's links.
# ----------------------------------------------------------------------------

# The lcm-gen C++ headers of every msgs/*.lcm type: include/sweptccd/sweptccd/.
install(DIRECTORY ${PROJECT_BINARY_DIR}/msgs/gen/sweptccd
        DESTINATION ${SWEPTCCD_INSTALL_INCLUDEDIR} COMPONENT dev
        FILES_MATCHING PATTERN "*.hpp")

# Dependencies of the exported targets: each linked item is an exported
# target, a known imported target (recreated by the config file) or an error.
get_property(sweptccd_exported GLOBAL PROPERTY SWEPTCCD_EXPORTED_TARGETS)
set(sweptccd_config_deps "")
set(sweptccd_pc_libs "")
set(sweptccd_dep_seen "")
foreach(target IN LISTS sweptccd_exported)
  set(sweptccd_pc_libs "-l$<TARGET_FILE_BASE_NAME:${target}> ${sweptccd_pc_libs}")
  get_target_property(links ${target} INTERFACE_LINK_LIBRARIES)
  if(NOT links)
    continue()
  endif()
  foreach(item IN LISTS links)
    string(REGEX REPLACE "^\\$<LINK_ONLY:(.*)>$" "\\1" item "${item}")
    if(item IN_LIST sweptccd_exported)
      continue()
    endif()
    set(how "")
    foreach(entry IN LISTS SWEPTCCD_EXPORT_DEPENDENCIES)
      string(REPLACE "|" ";" parts "${entry}")
      list(GET parts 0 dep_target)
      if(dep_target STREQUAL item)
        list(GET parts 1 how)
        list(LENGTH parts n)
        if(n GREATER 2)
          list(GET parts 2 pc_module)
          if(NOT pc_module STREQUAL "" AND NOT pc_module IN_LIST SWEPTCCD_PC_REQUIRES)
            list(APPEND SWEPTCCD_PC_REQUIRES ${pc_module})
          endif()
        endif()
      endif()
    endforeach()
    if(how STREQUAL "")
      message(FATAL_ERROR "Exported target ${target} links '${item}', which is neither an "
              "exported SweptCCD library nor in SWEPTCCD_EXPORT_DEPENDENCIES "
              "(cmake/packaging.cmake): export it or add it there.")
    endif()
    if(how IN_LIST sweptccd_dep_seen)
      continue()
    endif()
    list(APPEND sweptccd_dep_seen "${how}")
    if(how MATCHES "^pkg:([^:]+):(.+)$")
      string(APPEND sweptccd_config_deps
        "if(NOT TARGET PkgConfig::${CMAKE_MATCH_1})\n"
        "  pkg_check_modules(${CMAKE_MATCH_1} QUIET IMPORTED_TARGET ${CMAKE_MATCH_2})\n"
        "  if(NOT ${CMAKE_MATCH_1}_FOUND)\n"
        "    set(SweptCCD_FOUND FALSE)\n"
        "    set(SweptCCD_NOT_FOUND_MESSAGE \"SweptCCD needs pkg-config module ${CMAKE_MATCH_2}\")\n"
        "    return()\n"
        "  endif()\n"
        "endif()\n")
    elseif(how MATCHES "^cmake:(.+)$")
      string(APPEND sweptccd_config_deps "find_dependency(${CMAKE_MATCH_1})\n")
    endif()
  endforeach()
endforeach()
string(STRIP "${sweptccd_pc_libs}" sweptccd_pc_libs)

install(EXPORT SweptCCDTargets NAMESPACE SweptCCD:: FILE SweptCCDTargets.cmake
        DESTINATION ${SWEPTCCD_INSTALL_CMAKEDIR} COMPONENT dev)
set(SWEPTCCD_CONFIG_DEPENDENCIES "${sweptccd_config_deps}")
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/SweptCCDConfig.cmake.in
  ${PROJECT_BINARY_DIR}/cmake/SweptCCDConfig.cmake
  INSTALL_DESTINATION ${SWEPTCCD_INSTALL_CMAKEDIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/cmake/SweptCCDConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/cmake/SweptCCDConfig.cmake
              ${PROJECT_BINARY_DIR}/cmake/SweptCCDConfigVersion.cmake
        DESTINATION ${SWEPTCCD_INSTALL_CMAKEDIR} COMPONENT dev)

# sweptccd.pc: relocatable (prefix from the .pc file's own place).
set(pc_dir ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
file(RELATIVE_PATH SWEPTCCD_PC_TO_PREFIX /${pc_dir} /)
string(REGEX REPLACE "/$" "" SWEPTCCD_PC_TO_PREFIX "${SWEPTCCD_PC_TO_PREFIX}")
list(JOIN SWEPTCCD_PC_REQUIRES " " SWEPTCCD_PC_REQUIRES_LINE)
configure_file(${PROJECT_SOURCE_DIR}/cmake/sweptccd.pc.in
               ${PROJECT_BINARY_DIR}/cmake/sweptccd.pc.tmp @ONLY)
file(GENERATE OUTPUT ${PROJECT_BINARY_DIR}/cmake/sweptccd.pc
              INPUT ${PROJECT_BINARY_DIR}/cmake/sweptccd.pc.tmp)
install(FILES ${PROJECT_BINARY_DIR}/cmake/sweptccd.pc DESTINATION ${pc_dir} COMPONENT dev)

# --- Runtime: the daemon, the tool, the unit, the example configuration. ---
install(TARGETS sweptccd-service sweptccd RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
        COMPONENT runtime)
# The unit names /usr/local/bin/sweptccd-service (deploy/ installs by hand);
# installed, ExecStart names the installed daemon (resolved at install time,
# so cpack's /usr and `cmake --install --prefix P` are both right).
install(CODE "
  set(unit_dir \"\$ENV{DESTDIR}\${CMAKE_INSTALL_PREFIX}/lib/systemd/system\")
  file(READ \"${PROJECT_SOURCE_DIR}/deploy/sweptccd-service.service\" unit)
  string(REPLACE \"/usr/local/bin/sweptccd-service\"
                 \"\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_BINDIR}/sweptccd-service\" unit \"\${unit}\")
  file(MAKE_DIRECTORY \"\${unit_dir}\")
  message(STATUS \"Installing: \${unit_dir}/sweptccd-service.service\")
  file(WRITE \"\${unit_dir}/sweptccd-service.service\" \"\${unit}\")
  list(APPEND CMAKE_INSTALL_MANIFEST_FILES \"\${unit_dir}/sweptccd-service.service\")
" COMPONENT runtime)
install(FILES ${PROJECT_SOURCE_DIR}/deploy/sweptccd.yaml
              ${PROJECT_SOURCE_DIR}/deploy/sweptccd-service-gpu.conf
        DESTINATION ${SWEPTCCD_INSTALL_DOCDIR}/examples COMPONENT runtime)
install(FILES ${PROJECT_SOURCE_DIR}/README.md ${PROJECT_SOURCE_DIR}/docs/USAGE.md ${PROJECT_SOURCE_DIR}/docs/SERVICE.md
              ${PROJECT_SOURCE_DIR}/docs/SECURITY.md
        DESTINATION ${SWEPTCCD_INSTALL_DOCDIR} COMPONENT runtime)
# The live view of the WebSocket door (client/js, built at build time), where
# the daemon looks for it without --ws-view-dir: PREFIX/share/sweptccd/view.
if(TARGET sweptccd-js)
  install(DIRECTORY ${SWEPTCCD_VIEW_DIR}/ DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/sweptccd/view
          COMPONENT runtime)
endif()
# The Java classes of the message types (msgs/CMakeLists.txt), for lcm-spy.
if(TARGET sweptccd_msgs_jar)
  get_target_property(jar sweptccd_msgs_jar JAR_FILE)
  install(FILES ${jar} DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/java COMPONENT runtime)
endif()

# --- Debian packages: cpack -G DEB. ----------------------------------------
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME sweptccd)
set(CPACK_PACKAGE_VENDOR "SweptCCD")
set(CPACK_PACKAGE_CONTACT "SweptCCD maintainers <sweptccd@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "Continuous collision detection service for VR avatars (LCM)")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL runtime dev)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_COMPRESSION_TYPE gzip)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_RUNTIME_PACKAGE_NAME sweptccd)
# Depends: from dpkg-shlibdeps (Debian dpkg-dev) over the ELF files.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_RUNTIME_DESCRIPTION
    "The daemon sweptccd-service answers every pair of tracker poses received over\nLCM with the certified first time of contact; the sweptccd tool (query,\nsimulate-tracker, monitor, keygen, ...); a hardened systemd unit; an example\nconfiguration (/usr/share/doc/sweptccd/examples); the Java classes of the\nmessage types for lcm-spy (/usr/share/java/sweptccd_msgs.jar).")
set(CPACK_DEBIAN_DEV_PACKAGE_NAME sweptccd-dev)
set(CPACK_DEBIAN_DEV_PACKAGE_SECTION libdevel)
set(CPACK_DEBIAN_DEV_PACKAGE_DEPENDS
    "sweptccd (= ${PROJECT_VERSION}), liblcm-dev, libsodium-dev, libssl-dev, pkg-config")
set(CPACK_DEBIAN_DEV_DESCRIPTION
    "SweptCCD's static libraries and headers (LCM message types, checked decoding,\nmessage signing), the CMake package SweptCCD and the pkg-config file sweptccd.")
include(CPack)
