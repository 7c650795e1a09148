# The numerical stress suite (issue 5; docs/stress.md): furnace, analytic
# plane, invariance under scale/translation/rotation, hard geometry, degenerate
# input files (tests/data/stress/) and kd-tree extremes. One program,
# test_stress, one ctest per group, all labelled `stress`.
pf_add_test(stress_furnace ${CMAKE_CURRENT_LIST_DIR}/test_stress.c LIBS pf_coordinator ARGS furnace LABELS stress)
set_target_properties(test_stress_furnace PROPERTIES OUTPUT_NAME test_stress)
foreach(group plane invariance geometry degenerate kdtree)
  add_test(NAME stress_${group} COMMAND test_stress_furnace ${group} WORKING_DIRECTORY ${CMAKE_SOURCE_DIR})
  set_tests_properties(stress_${group} PROPERTIES LABELS stress)
endforeach()
