# Finds what the Python bindings (python/) need and sets BLOT_BUILD_PYTHON.
#
# The interpreter is Debian's /usr/bin/python3 unless Python_EXECUTABLE is
# given: numpy, pybind11, Dask and matplotlib are Debian packages installed for
# it, and another python3 earlier on PATH would not see them.
set(_blot_python_default OFF)
# Not in sanitizer or fuzz builds: an instrumented module cannot be loaded
# into an uninstrumented interpreter.
if(BLOT_IS_TOP_LEVEL AND NOT BLOT_SANITIZE AND NOT BLOT_FUZZ)
  if(NOT Python_EXECUTABLE AND EXISTS /usr/bin/python3)
    set(Python_EXECUTABLE /usr/bin/python3 CACHE FILEPATH "Interpreter the Python bindings are built for")
  endif()
  find_package(Python 3.8 QUIET COMPONENTS Interpreter Development.Module)
  if(Python_FOUND)
    find_package(pybind11 2.6 QUIET CONFIG)
  endif()
  if(Python_FOUND AND pybind11_FOUND)
    execute_process(COMMAND ${Python_EXECUTABLE} -c "import numpy"
                    RESULT_VARIABLE _blot_numpy_rc OUTPUT_QUIET ERROR_QUIET)
    if(_blot_numpy_rc EQUAL 0)
      set(_blot_python_default ON)
    endif()
  endif()
endif()
option(BLOT_BUILD_PYTHON "Build the Python module `blot` (python/; pybind11, numpy)" ${_blot_python_default})
if(BLOT_BUILD_PYTHON)
  if(NOT Python_FOUND)
    find_package(Python 3.8 REQUIRED COMPONENTS Interpreter Development.Module)
  endif()
  if(NOT pybind11_FOUND)
    find_package(pybind11 2.6 REQUIRED CONFIG)
  endif()
  message(STATUS "Python bindings: building for ${Python_EXECUTABLE} (${Python_VERSION}), pybind11 ${pybind11_VERSION}")
else()
  message(STATUS "Python bindings: not built (needs pybind11-dev, python3-dev, python3-numpy for /usr/bin/python3, or BLOT_BUILD_PYTHON=OFF)")
endif()
unset(_blot_python_default)
