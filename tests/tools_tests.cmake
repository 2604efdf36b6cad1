# The four tools (tools/), run as a user would: shell scripts in tests/cli,
# each named for what it checks, fixtures in tests/data/cli. Each script gets
# the tools' directory, the source tree and the shared scenes directory.
set(_as_cli_tests
  tools_answer_help_version_and_usage_errors
  build_rejects_bad_meshes
  build_bunny_summary_and_atomic_replace
  inspect_reports_same_facts_in_json_and_text
  inspect_json_escapes_file_name
  damaged_files_are_refused
  validate_catches_damage_without_checksums
  validate_checks_meta_counts_against_arrays
  convert_compress_round_trip
  trace_rays_file_gives_known_hits_and_image
  trace_heat_map_colours_steps_per_ray
  trace_rebuild_beside_load
  trace_whitted_materials_from_mtl
  trace_validation_record_skips_known_files
  trace_camera_file_matches_options
  trace_ray_limit_traces_first_rays
  trace_dump_rays_trace_back_to_the_same_hits
  bench_scene_writes_every_workload
  bench_sweep_writes_protocol_and_sweeps
  gpu_validation_refuses_damage
  other_scenes_build_inspect_trace
  stiff_cases_meet_their_outcomes)
foreach(_t ${_as_cli_tests})
  add_test(NAME cli_${_t}
    COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/cli/${_t}.sh $<TARGET_FILE_DIR:as-build>
            ${PROJECT_SOURCE_DIR} ${AS_SCENES_DIR})
  set_tests_properties(cli_${_t} PROPERTIES SKIP_RETURN_CODE 77 LABELS cli)
endforeach()
set_tests_properties(cli_other_scenes_build_inspect_trace PROPERTIES LABELS "cli;scenes")
set_tests_properties(cli_bench_sweep_writes_protocol_and_sweeps PROPERTIES LABELS "cli;scenes")
set_tests_properties(cli_gpu_validation_refuses_damage PROPERTIES LABELS "cli;gpu")

# tools/as-study (label tools): two partial studies of the bundled bunny on the
# CPU at a tiny image, merged with --merge and compared with one run of both.
add_test(NAME tools_as_study_merge
  COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/cli/check_study_merge.py $<TARGET_FILE_DIR:as-build>
          ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_BINARY_DIR}/as-study-merge-out)
set_tests_properties(tools_as_study_merge PROPERTIES LABELS tools TIMEOUT 300)
# Its two compressed wide BVH rows on the bunny: sensible figures, 0
# mismatches, marked as ours in the report; --merge with a merged folder
# made before them, and of the H100 study's San Miguel.
add_test(NAME tools_as_study_cwbvh_rows
  COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/cli/check_study_cwbvh.py $<TARGET_FILE_DIR:as-build>
          ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_BINARY_DIR}/as-study-cwbvh-out)
set_tests_properties(tools_as_study_cwbvh_rows PROPERTIES LABELS tools TIMEOUT 300)
# --check: a committed study run again with its recorded settings agrees;
# a figure changed by hand is found; another scene is refused.
add_test(NAME tools_as_study_check
  COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/cli/check_study_check.py $<TARGET_FILE_DIR:as-build>
          ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_BINARY_DIR}/as-study-check-out)
set_tests_properties(tools_as_study_check PROPERTIES LABELS tools TIMEOUT 300)
# All thirteen variants on a scene made by the test (not one of ../shared/scenes
# nor the bunny): every output, 0 mismatches, and --check of what it wrote.
add_test(NAME tools_as_study_other_scene
  COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/cli/check_study_other_scene.py $<TARGET_FILE_DIR:as-build>
          ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_BINARY_DIR}/as-study-other-out)
set_tests_properties(tools_as_study_other_scene PROPERTIES LABELS tools TIMEOUT 300)
# scripts/other_scenes.py, which the GPU host runs in full (hills, a city of
# 25,000 boxes, the watertight sphere at 1e6): here its --quick form on the
# CPU with 300 boxes; exit 0 only when every verified ray agreed.
add_test(NAME scripts_other_scenes_quick
  COMMAND ${PROJECT_SOURCE_DIR}/scripts/other_scenes.py ${CMAKE_CURRENT_BINARY_DIR}/other-scenes-out
          --bin $<TARGET_FILE_DIR:as-build> --device cpu --quick --boxes 300)
set_tests_properties(scripts_other_scenes_quick PROPERTIES LABELS tools TIMEOUT 300)
# scripts/ceiling.py: node visits per second against the H100's ceilings, on
# a study folder whose figures are known.
add_test(NAME tools_ceiling_table
  COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/cli/check_ceiling.py ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_BINARY_DIR}/ceiling-out)
set_tests_properties(tools_ceiling_table PROPERTIES LABELS tools)
