# install.find_package: install the build into a temporary prefix, then
# build examples/use_library against it with find_package (shared and
# static) and with pkg-config, and run each.  Run with cmake -P and
#   -DBUILD_DIR -DSOURCE_DIR -DWORK_DIR -DLIBDIR -DC_COMPILER [-DEXTRA_FLAGS]
cmake_minimum_required(VERSION 3.25)

function(run what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rv OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rv EQUAL 0)
    message(FATAL_ERROR "FAIL: ${what} (exit ${rv})\n${out}\n${err}")
  endif()
  set(run_out "${out}" PARENT_SCOPE)
endfunction()

set(prefix ${WORK_DIR}/prefix)
file(REMOVE_RECURSE ${WORK_DIR})
run("cmake --install" ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix})
foreach(f bin/sepbrdf ${LIBDIR}/libsepbrdf.so ${LIBDIR}/libsepbrdf.a include/sepbrdf/sepbrdf.h
        include/sepbrdf/factor.h share/sepbrdf/sepbrdf.glsl ${LIBDIR}/pkgconfig/sepbrdf.pc
        ${LIBDIR}/cmake/sepbrdf/sepbrdfConfig.cmake ${LIBDIR}/cmake/sepbrdf/sepbrdfConfigVersion.cmake
        ${LIBDIR}/cmake/sepbrdf/sepbrdfTargets.cmake)
  if(NOT EXISTS ${prefix}/${f})
    message(FATAL_ERROR "FAIL: ${f} not installed")
  endif()
endforeach()
run("installed CLI --version" ${prefix}/bin/sepbrdf --version)

# find_package, both libraries
set(flags "")
if(EXTRA_FLAGS)
  set(flags -DCMAKE_C_FLAGS=${EXTRA_FLAGS} -DCMAKE_EXE_LINKER_FLAGS=${EXTRA_FLAGS})
endif()
foreach(static OFF ON)
  set(b ${WORK_DIR}/build-static-${static})
  run("configure example (USE_STATIC=${static})" ${CMAKE_COMMAND} -S ${SOURCE_DIR}/examples/use_library -B ${b}
      -DCMAKE_PREFIX_PATH=${prefix} -DCMAKE_C_COMPILER=${C_COMPILER} -DUSE_STATIC=${static} ${flags})
  run("build example (USE_STATIC=${static})" ${CMAKE_COMMAND} --build ${b})
  run("run example (USE_STATIC=${static})" ${b}/use_library lambert:albedo=0.5 8 2 ${b}/out)
  if(NOT run_out MATCHES "rel_rms" OR NOT run_out MATCHES "kept" OR NOT EXISTS ${b}/out/report.json)
    message(FATAL_ERROR "FAIL: unexpected example output:\n${run_out}")
  endif()
  message(STATUS "find_package, USE_STATIC=${static}: ok\n${run_out}")
endforeach()

# pkg-config
find_program(PKG_CONFIG NAMES pkg-config pkgconf REQUIRED)
set(ENV{PKG_CONFIG_PATH} ${prefix}/${LIBDIR}/pkgconfig)
run("pkg-config --cflags --libs sepbrdf" ${PKG_CONFIG} --cflags --libs sepbrdf)
string(STRIP "${run_out}" pc_flags)
message(STATUS "pkg-config --cflags --libs sepbrdf: ${pc_flags}")
if(NOT pc_flags MATCHES "-lsepbrdf")
  message(FATAL_ERROR "FAIL: pkg-config output lacks -lsepbrdf: ${pc_flags}")
endif()
run("pkg-config includedir" ${PKG_CONFIG} --variable=includedir sepbrdf)
string(STRIP "${run_out}" incdir)
if(NOT EXISTS ${incdir}/sepbrdf/sepbrdf.h)
  message(FATAL_ERROR "FAIL: pkg-config includedir ${incdir} has no sepbrdf/sepbrdf.h")
endif()
separate_arguments(pc_list UNIX_COMMAND "${pc_flags}")
separate_arguments(extra UNIX_COMMAND "${EXTRA_FLAGS}")
run("cc with pkg-config flags" ${C_COMPILER} ${extra} ${SOURCE_DIR}/examples/use_library/main.c ${pc_list}
    -o ${WORK_DIR}/use_library_pc)
set(ENV{LD_LIBRARY_PATH} ${prefix}/${LIBDIR})
run("run the pkg-config build" ${WORK_DIR}/use_library_pc lambert:albedo=0.5 8 2 ${WORK_DIR}/out-pc)
if(NOT run_out MATCHES "rel_rms")
  message(FATAL_ERROR "FAIL: unexpected output:\n${run_out}")
endif()
message(STATUS "pkg-config: ok")
