# What `cmake --install` puts under the prefix (README, "Install and embed"):
#   lib/            libblot_{stain,cloth,coupling,engine,outputs}.a
#   include/blot/   the public headers (C++ and the C API blot.h)
#   lib/cmake/Blot/ BlotConfig.cmake, its version file and the exported targets
#                   Blot::stain, Blot::cloth, Blot::coupling, Blot::engine,
#                   Blot::outputs (find_package(Blot 0.1 CONFIG))
#   lib/pkgconfig/  blot.pc (the engine core and the C API), blot-outputs.pc
#   bin/blot        the command line, when the demos are built
#   share/blot/     assets/ (scenes, patterns) that `blot` finds beside itself
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(BLOT_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/Blot CACHE STRING
    "Where BlotConfig.cmake is installed, relative to the prefix")
mark_as_advanced(BLOT_INSTALL_CMAKEDIR)

set(_blot_libraries blot_stain blot_cloth blot_coupling blot_engine blot_outputs)
install(TARGETS ${_blot_libraries}
        EXPORT BlotTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
foreach(_dir stain/include cloth/include coupling/include engine/include engine/outputs/include)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${_dir}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
          FILES_MATCHING PATTERN "*.h")
endforeach()

install(EXPORT BlotTargets NAMESPACE Blot:: DESTINATION ${BLOT_INSTALL_CMAKEDIR})
# OpenEXR is a dependency of the installed package only where it was built in.
if(BLOT_HAVE_OPENEXR)
  set(BLOT_FIND_OPENEXR "find_dependency(OpenEXR 3 CONFIG)  # float EXR stain maps in Blot::outputs")
  set(BLOT_PC_OPENEXR " OpenEXR")
else()
  set(BLOT_FIND_OPENEXR "# built without OpenEXR: no EXR stain maps")
  set(BLOT_PC_OPENEXR "")
endif()
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/BlotConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/BlotConfig.cmake
                              INSTALL_DESTINATION ${BLOT_INSTALL_CMAKEDIR})
# 0.x: a minor version may break the API, so only the same major.minor is
# compatible (find_package(Blot 0.1) accepts 0.1.*, not 0.2).
write_basic_package_version_file(${PROJECT_BINARY_DIR}/BlotConfigVersion.cmake
                                 VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/BlotConfig.cmake ${PROJECT_BINARY_DIR}/BlotConfigVersion.cmake
              ${PROJECT_SOURCE_DIR}/cmake/FindCHOLMOD.cmake ${PROJECT_SOURCE_DIR}/cmake/BlotBulletTarget.cmake
        DESTINATION ${BLOT_INSTALL_CMAKEDIR})

# pkg-config. The libraries are static archives, so what they link privately
# (CHOLMOD, Bullet, tinyobjloader, OpenMP, the C++ runtime) is in Libs, not
# Libs.private: `pkg-config --libs blot` is a complete link line.
file(RELATIVE_PATH BLOT_PC_PREFIX_FROM_PCDIR ${CMAKE_INSTALL_FULL_LIBDIR}/pkgconfig ${CMAKE_INSTALL_PREFIX})
configure_file(${PROJECT_SOURCE_DIR}/cmake/blot.pc.in ${PROJECT_BINARY_DIR}/blot.pc @ONLY)
configure_file(${PROJECT_SOURCE_DIR}/cmake/blot-outputs.pc.in ${PROJECT_BINARY_DIR}/blot-outputs.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/blot.pc ${PROJECT_BINARY_DIR}/blot-outputs.pc
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)

# The command line and the assets it opens by default (demo and figure scenes,
# weave patterns), found relative to bin/blot as ../share/blot/.
if(TARGET blot)
  install(TARGETS blot RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/assets/ DESTINATION ${CMAKE_INSTALL_DATADIR}/blot/assets)
  # The CGAL sample meshes (scripts/setup), where the bunny scenes' relative
  # paths (../../build/external/meshes/) and `blot demo drop-diffusion` look.
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/build/external/meshes/
          DESTINATION ${CMAKE_INSTALL_DATADIR}/blot/build/external/meshes OPTIONAL)
endif()
unset(_blot_libraries)
