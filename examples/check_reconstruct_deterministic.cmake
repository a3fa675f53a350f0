# CTest script: `difftrans reconstruct` with one seed gives the same files
# bit for bit on 1 and on 3 threads (fixed blocks of work, sums in a fixed
# order); another seed gives another fit. With the vertices moving over
# three levels of blur, reconstruct.json traces the surface against the true
# mesh at the start and at the end of each level (materials.geometry_levels).
# The loss checks at those levels (--materials-level-batches) draw batches of
# their own: without them the fit is the same, bit for bit.
# Arguments: -DCOMMAND=path/to/difftrans -DSCENE=scene directory -DWORK_DIR=folder
set(options --stages environment,geometry,materials --grid 16 --iterations 20 --refine-iterations 10
            --materials-iterations 12 --materials-freeze 4 --materials-rays 512 --materials-blur-halving 3
            --restart)
set(outputs mesh_stage1_raw.obj mesh_stage1.obj mesh_stage2.obj material_stage2.json absorption_stage2.json envmap.hdr
            geometry_stage2.png)
foreach(run IN ITEMS 1 3)
  execute_process(COMMAND ${CMAKE_COMMAND} -E env DIFFTRANS_THREADS=${run}
                          ${COMMAND} reconstruct ${SCENE} --out ${WORK_DIR}/threads${run} ${options} --seed 5
                  RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "reconstruct on ${run} threads failed (${rc}): ${err}")
  endif()
endforeach()
# the level checks off: they must not touch the fit's random stream or state
# (stage 2 alone, again, in a copy of the 1-thread run: the same stage-1 mesh and map)
file(REMOVE_RECURSE ${WORK_DIR}/nolevels)
file(COPY ${WORK_DIR}/threads1/ DESTINATION ${WORK_DIR}/nolevels)
file(REMOVE ${WORK_DIR}/nolevels/mesh_stage2.obj ${WORK_DIR}/nolevels/material_stage2.json)
set(materials_only ${options})
list(TRANSFORM materials_only REPLACE "^environment,geometry,materials$" "materials")
execute_process(COMMAND ${CMAKE_COMMAND} -E env DIFFTRANS_THREADS=1
                        ${COMMAND} reconstruct ${SCENE} --out ${WORK_DIR}/nolevels ${materials_only} --seed 5
                        --materials-level-batches 0
                RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "reconstruct without level checks failed (${rc}): ${err}")
endif()
# expect_same(A B HOW FILES...): each file the same bit for bit in folders A and B ("... differs HOW" if not);
# the grid file only when the absorption model chosen is a grid: then in both
function(expect_same a b how)
  foreach(f IN LISTS ARGN)
    if(NOT EXISTS ${a}/${f} AND NOT EXISTS ${b}/${f} AND f STREQUAL "absorption_stage2.json")
      continue()
    endif()
    execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${a}/${f} ${b}/${f} RESULT_VARIABLE diff)
    if(NOT diff EQUAL 0)
      message(FATAL_ERROR "${f} differs ${how}")
    endif()
  endforeach()
endfunction()
expect_same(${WORK_DIR}/threads1 ${WORK_DIR}/nolevels "with and without the level checks (--materials-level-batches 0)"
            mesh_stage2.obj material_stage2.json)
expect_same(${WORK_DIR}/threads1 ${WORK_DIR}/threads3 "between 1 and 3 threads with the same seed" ${outputs})
# the level trace: iterations 4 (stage 1), 7 and 10 (new blurs), 12 (the end)
file(READ ${WORK_DIR}/threads1/reconstruct.json record)
string(JSON levels ERROR_VARIABLE missing GET "${record}" materials geometry_levels)
if(missing)
  message(FATAL_ERROR "reconstruct.json has no materials.geometry_levels: ${missing}")
endif()
string(JSON count LENGTH "${levels}")
if(NOT count EQUAL 4)
  message(FATAL_ERROR "materials.geometry_levels has ${count} entries, 4 expected: ${levels}")
endif()
set(expected_iterations 4 7 10 12)
foreach(k RANGE 3)
  string(JSON it GET "${levels}" ${k} iteration)
  string(JSON after GET "${levels}" ${k} after)
  string(JSON normals GET "${levels}" ${k} normal_error_deg mean)
  string(JSON chamfer GET "${levels}" ${k} chamfer)
  list(GET expected_iterations ${k} want)
  if(NOT it EQUAL want OR NOT normals GREATER 0 OR NOT chamfer GREATER 0)
    message(FATAL_ERROR "geometry_levels[${k}]: iteration ${it} (expected ${want}), normals ${normals}, chamfer ${chamfer}")
  endif()
endforeach()
string(JSON first GET "${levels}" 0 after)
if(NOT first STREQUAL "stage 1")
  message(FATAL_ERROR "geometry_levels starts at '${first}', not the stage-1 mesh")
endif()
execute_process(COMMAND ${COMMAND} reconstruct ${SCENE} --out ${WORK_DIR}/seed6 ${options} --seed 6
                RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "reconstruct with seed 6 failed (${rc}): ${err}")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${WORK_DIR}/threads1/material_stage2.json
                        ${WORK_DIR}/seed6/material_stage2.json RESULT_VARIABLE diff)
if(diff EQUAL 0)
  message(FATAL_ERROR "seeds 5 and 6 gave the same material")
endif()
message(STATUS "reconstruct: identical on 1 and 3 threads and without the level checks; another seed gives another fit")
