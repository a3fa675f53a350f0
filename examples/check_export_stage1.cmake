# CTest script: `difftrans export` of a reconstruction that has only stage 1's
# mesh falls back to it (saying so, with a default material); a folder with no
# mesh at all is refused, naming it.
# Arguments: -DCOMMAND=path/to/difftrans -DMESH=a mesh -DWORK_DIR=folder
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR}/recon)
file(COPY_FILE ${MESH} ${WORK_DIR}/recon/mesh_stage1.obj)
execute_process(COMMAND ${COMMAND} export ${WORK_DIR}/recon --format obj --out ${WORK_DIR}/out
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "export of a stage-1 reconstruction failed (${rc}): ${err}")
endif()
if(NOT err MATCHES "mesh_stage2.obj not found \\(stage 2, materials, has not run\\): exporting the stage-1 mesh")
  message(FATAL_ERROR "export did not say it fell back to the stage-1 mesh: ${err}")
endif()
if(NOT err MATCHES "material_stage2.json not found" OR NOT out MATCHES "\"ior\": 1.5")
  message(FATAL_ERROR "export did not say it used the default material: ${err} ${out}")
endif()
foreach(f mesh.obj material.json export.json)
  if(NOT EXISTS ${WORK_DIR}/out/${f})
    message(FATAL_ERROR "export wrote no ${f}")
  endif()
endforeach()
if(EXISTS ${WORK_DIR}/out.partial)
  message(FATAL_ERROR "export left ${WORK_DIR}/out.partial behind")
endif()
# without the mesh: refused, nothing written
file(REMOVE ${WORK_DIR}/recon/mesh_stage1.obj)
execute_process(COMMAND ${COMMAND} export ${WORK_DIR}/recon --format gltf --out ${WORK_DIR}/never
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(rc EQUAL 0 OR NOT err MATCHES "recon: no reconstructed mesh here")
  message(FATAL_ERROR "export of a folder without results did not fail naming it (${rc}): ${err}")
endif()
if(EXISTS ${WORK_DIR}/never OR EXISTS ${WORK_DIR}/never.partial)
  message(FATAL_ERROR "a failed export left ${WORK_DIR}/never behind")
endif()
