# A fresh install of BUILD_DIR into PREFIX (the consumers' package).
file(REMOVE_RECURSE "${PREFIX}")
set(config_args)
if(CONFIG)
  set(config_args --config "${CONFIG}")
endif()
execute_process(COMMAND "${CMAKE_COMMAND}" --install "${BUILD_DIR}" --prefix "${PREFIX}" ${config_args}
                RESULT_VARIABLE result OUTPUT_QUIET)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "cmake --install ${BUILD_DIR} --prefix ${PREFIX} failed (${result})")
endif()
foreach(file ${LIBDIR}/cmake/Blot/BlotConfig.cmake ${LIBDIR}/cmake/Blot/BlotConfigVersion.cmake
             ${LIBDIR}/pkgconfig/blot.pc include/blot/blot.h)
  if(NOT EXISTS "${PREFIX}/${file}")
    message(FATAL_ERROR "the install lacks ${file}")
  endif()
endforeach()
message(STATUS "installed Blot into ${PREFIX}")
