# The farm's integration and fault tests (tests/test_farm.sh): real
# coordinator and worker processes over loopback, local workers, kill -9,
# SIGSTOP, late joiners, crafted frames from tests/pf_inject.c, a foreign
# protocol version, CURVE admission, Ctrl-C and long-lived workers. Every
# image is compared bit for bit with the in-process render.
add_executable(pf_inject ${CMAKE_CURRENT_SOURCE_DIR}/pf_inject.c)
target_link_libraries(pf_inject PRIVATE pf_proto PkgConfig::ZMQ)

if(TARGET photonfarm AND TARGET photonfarm-worker)
  add_test(NAME farm
           COMMAND bash ${CMAKE_SOURCE_DIR}/tests/test_farm.sh $<TARGET_FILE:photonfarm>
                   $<TARGET_FILE:photonfarm-worker> $<TARGET_FILE:pf_inject>
           WORKING_DIRECTORY ${CMAKE_SOURCE_DIR})
  set_tests_properties(farm PROPERTIES LABELS "integration" TIMEOUT 600)
else()
  message(STATUS "farm test skipped: no photonfarm-worker target yet")
endif()
