# Installs difftrans into a temporary prefix and builds a small outside
# project against it with find_package(difftrans), then runs its programs:
# the core, io with host tracing, and Eigen when the build had it. Run by
# CTest; DISABLED (packages, comma-separated: embree,Eigen3) leaves out of the installed
# build what the build under test left out.
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})

function(run)
  execute_process(COMMAND ${ARGN} WORKING_DIRECTORY ${WORK_DIR} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
endfunction()

set(disabled "")
string(REPLACE "," ";" disabled_packages "${DISABLED}")
foreach(package IN LISTS disabled_packages)
  list(APPEND disabled -DCMAKE_DISABLE_FIND_PACKAGE_${package}=ON)
endforeach()
run(${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${WORK_DIR}/build -DCMAKE_INSTALL_PREFIX=${WORK_DIR}/prefix
    -DDIFFTRANS_BUILD_TESTS=OFF -DDIFFTRANS_BUILD_BENCH=OFF -DDIFFTRANS_BUILD_EXAMPLES=OFF -DDIFFTRANS_CUDA=OFF
    ${disabled})
run(${CMAKE_COMMAND} --install ${WORK_DIR}/build)
run(${CMAKE_COMMAND} -S ${CONSUMER_DIR} -B ${WORK_DIR}/consumer -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix)
run(${CMAKE_COMMAND} --build ${WORK_DIR}/consumer)
run(${WORK_DIR}/consumer/consumer)
run(${WORK_DIR}/consumer/consumer_io ${WORK_DIR})
if(EXISTS ${WORK_DIR}/consumer/consumer_eigen)
  run(${WORK_DIR}/consumer/consumer_eigen)
endif()
message(STATUS "installed package found and used by an outside project")
