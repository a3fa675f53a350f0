# CTest script: the comparisons with a scene's gt/ files are reports. A copy
# of the tiny scene with a ground-truth material the reader refuses (an
# unknown absorption type) and a mesh with no surface runs all three stages
# to the end: each bad file is warned about, reconstruct.json holds every
# stage's record and names what was left out. And a copy whose masks are all
# empty stops at load, before any stage, with "no foreground pixel in any mask".
# Arguments: -DCOMMAND=path/to/difftrans -DSCENE=scene directory -DWORK_DIR=folder
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})
file(COPY ${SCENE}/ DESTINATION ${WORK_DIR}/scene)
file(READ ${WORK_DIR}/scene/gt/material.json material)
string(REGEX REPLACE "\"type\": \"[a-z]+\"" "\"type\": \"mystery\"" material "${material}")
file(WRITE ${WORK_DIR}/scene/gt/material.json "${material}")
file(WRITE ${WORK_DIR}/scene/gt/mesh.obj "v 0 0 0\nv 1 0 0\n")
execute_process(COMMAND ${COMMAND} reconstruct ${WORK_DIR}/scene --out ${WORK_DIR}/out
                        --stages environment,geometry,materials --env-width 32 --grid 10 --iterations 12 --batch 2
                        --refine-iterations 4 --refine-batch 2 --metric-samples 2000 --materials-iterations 6
                        --materials-freeze 3 --materials-rays 256 --absorption-res 4 --test-spp-axis 1 --restart
                RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "reconstruct failed (${rc}) on a scene whose gt/ files are bad: ${err}")
endif()
foreach(warning IN ITEMS "gt/material.json: absorption.type: 'mystery' is none of"
                         "the comparison with the ground-truth material is left out"
                         "gt/mesh.obj: no surface to compare with")
  string(FIND "${err}" "${warning}" at)
  if(at EQUAL -1)
    message(FATAL_ERROR "no warning '${warning}' in: ${err}")
  endif()
endforeach()
file(READ ${WORK_DIR}/out/reconstruct.json record)
foreach(key IN ITEMS environment geometry materials ground_truth_skipped)
  string(JSON value ERROR_VARIABLE missing GET "${record}" ${key})
  if(missing)
    message(FATAL_ERROR "reconstruct.json has no ${key}: ${record}")
  endif()
endforeach()
string(JSON ior GET "${record}" materials ior)
string(JSON skipped LENGTH "${record}" ground_truth_skipped)
if(NOT skipped EQUAL 2)
  message(FATAL_ERROR "ground_truth_skipped lists ${skipped} files, expected 2")
endif()

# every mask empty (degrade erodes the 16 x 16 masks by 20 pixels): refused at load, naming the file
execute_process(COMMAND ${COMMAND} degrade ${SCENE} --out ${WORK_DIR}/empty_masks --mask-erode 20
                RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "degrade failed (${rc}): ${err}")
endif()
execute_process(COMMAND ${COMMAND} reconstruct ${WORK_DIR}/empty_masks --out ${WORK_DIR}/never --stages geometry
                RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
string(FIND "${err}" "empty_masks/transforms_train.json: no foreground pixel in any mask" at)
if(rc EQUAL 0 OR at EQUAL -1)
  message(FATAL_ERROR "a scene with every mask empty was not refused at load (${rc}): ${err}")
endif()
if(EXISTS ${WORK_DIR}/never/mesh_stage1_raw.obj)
  message(FATAL_ERROR "a stage ran on a scene with every mask empty")
endif()
message(STATUS "bad gt/ files: warned and left out, ior ${ior} recorded; empty masks: refused at load")
