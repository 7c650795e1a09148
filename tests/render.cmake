# The renderer end to end: furnace, thread/tile determinism, accuracy against references.
pf_add_test(render_furnace test_render.c LIBS pf_coordinator ARGS furnace LABELS integration)
add_test(NAME render_determinism COMMAND test_render_furnace determinism WORKING_DIRECTORY ${CMAKE_SOURCE_DIR})
add_test(NAME render_accuracy COMMAND test_render_furnace accuracy WORKING_DIRECTORY ${CMAKE_SOURCE_DIR})
set_tests_properties(render_determinism PROPERTIES LABELS integration)
set_tests_properties(render_accuracy PROPERTIES LABELS accuracy)
