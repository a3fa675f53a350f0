# CTest script: `reconstruct --stages environment` chooses the environment
# model from the background pixels, not from scene.json. Two small scenes
# are made here, each with scene.json's "environment" set to the WRONG
# model: the object in a textured room (parallax: must come out "near") and
# the object under a distant map (must come out "distant"). 40 views: with
# 10, the views' backgrounds hardly overlap and there is nothing to compare.
# Arguments: -DCOMMAND=path/to/difftrans -DWORK_DIR=folder
set(synth_options --preset spot-clear --variant test --resolution 24 --views 40 --test-views 2 --spp-axis 1 --overwrite)
set(fit_options --stages environment --field-resolutions 16,32 --field-iterations 40,60 --env-choice-iterations 40,60
                --field-batch 1024 --env-width 64 --restart)
foreach(case IN ITEMS room:near far:distant)
  string(REPLACE ":" ";" parts ${case})
  list(GET parts 0 name)
  list(GET parts 1 expected)
  set(extra "")
  if(name STREQUAL "room")
    set(extra --room)
  endif()
  execute_process(COMMAND ${COMMAND} synth ${synth_options} ${extra} --out ${WORK_DIR}/${name}
                  RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "synth ${name} failed (${rc}): ${err}")
  endif()
  # the hint says the other model
  file(READ ${WORK_DIR}/${name}/scene.json scene_json)
  if(expected STREQUAL "near")
    set(wrong distant)
  else()
    set(wrong near)
  endif()
  string(JSON scene_json SET "${scene_json}" environment "\"${wrong}\"")
  file(WRITE ${WORK_DIR}/${name}/scene.json "${scene_json}")
  execute_process(COMMAND ${COMMAND} reconstruct ${WORK_DIR}/${name} --out ${WORK_DIR}/${name}_out ${fit_options}
                  RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "reconstruct ${name} failed (${rc}): ${err}")
  endif()
  file(READ ${WORK_DIR}/${name}_out/reconstruct.json record)
  string(JSON decision GET "${record}" environment choice decision)
  string(JSON hint GET "${record}" environment choice hint)
  string(JSON reason GET "${record}" environment choice reason)
  if(NOT hint STREQUAL wrong)
    message(FATAL_ERROR "${name}: the choice saw the hint \"${hint}\", not the \"${wrong}\" written in scene.json")
  endif()
  if(NOT decision STREQUAL expected)
    message(FATAL_ERROR "${name}: chose \"${decision}\" (${reason}), expected \"${expected}\"")
  endif()
  message(STATUS "${name}: ${decision} against scene.json's \"${wrong}\" (${reason})")
endforeach()
