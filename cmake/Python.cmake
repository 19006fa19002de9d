# Finds what the Python module needs and sets the option AREOMAP_PYTHON (default: ON where all
# of it is found): an interpreter that imports NumPy, its headers (Development.Module) and
# pybind11 (Debian: python3-dev, python3-numpy, pybind11-dev; scripts/install-deps.sh).
#
# The interpreter is the first `python3` on PATH that imports numpy (a pyenv or virtualenv
# python without NumPy is passed over for the system one); -DPython3_EXECUTABLE=... picks one.
function(areomap_python_imports_numpy result candidate)
  execute_process(COMMAND "${candidate}" -c "import numpy" RESULT_VARIABLE status
                  OUTPUT_QUIET ERROR_QUIET)
  if(NOT status EQUAL 0)
    set(${result} FALSE PARENT_SCOPE)
  endif()
endfunction()

set(areomap_python_found FALSE)
if(NOT AREOMAP_FUZZ AND NOT AREOMAP_SANITIZE)
  if(NOT Python3_EXECUTABLE)
    find_program(AREOMAP_PYTHON3_WITH_NUMPY NAMES python3
                 VALIDATOR areomap_python_imports_numpy)
    if(AREOMAP_PYTHON3_WITH_NUMPY)
      set(Python3_EXECUTABLE "${AREOMAP_PYTHON3_WITH_NUMPY}")
    endif()
  endif()
  find_package(Python3 3.8 QUIET COMPONENTS Interpreter Development.Module)
  if(Python3_FOUND)
    find_package(pybind11 2.6 CONFIG QUIET)
    set(numpy_found TRUE)
    areomap_python_imports_numpy(numpy_found "${Python3_EXECUTABLE}")
    if(pybind11_FOUND AND numpy_found)
      set(areomap_python_found TRUE)
    endif()
  endif()
endif()

option(AREOMAP_PYTHON "Build the Python module areomap (pybind11)" ${areomap_python_found})
if(AREOMAP_PYTHON AND NOT areomap_python_found)
  message(FATAL_ERROR
    "AREOMAP_PYTHON is ON but its dependencies are missing: a python3 that imports numpy "
    "(python3-numpy), Python headers (python3-dev) and pybind11 (pybind11-dev); install them "
    "with scripts/install-deps.sh or configure with -DAREOMAP_PYTHON=OFF (the module is not "
    "built with AREOMAP_SANITIZE or AREOMAP_FUZZ)")
elseif(AREOMAP_PYTHON)
  message(STATUS "Python module: ${Python3_EXECUTABLE} (${Python3_VERSION}), pybind11 "
                 "${pybind11_VERSION}")
elseif(AREOMAP_FUZZ OR AREOMAP_SANITIZE)
  message(STATUS "Python module: off (not built with AREOMAP_SANITIZE or AREOMAP_FUZZ)")
elseif(areomap_python_found)
  message(STATUS "Python module: off (AREOMAP_PYTHON=OFF)")
else()
  message(STATUS "Python module: off (needs pybind11-dev, python3-dev and python3-numpy)")
endif()
