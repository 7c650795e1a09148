# The deploy recipes (tests/test_deploy.sh, ctest deploy, label unit):
# shellcheck, systemd-analyze verify, yamllint and a structural check of the
# Kubernetes manifests, the Secret's keys in a real CURVE render, the Slurm
# script with stand-in srun/scontrol, the Containerfile's copy list and
# runtime packages, cmake --install. A missing tool is a SKIP line.
#
# The farm across network namespaces (tests/test_cluster.sh, ctest cluster,
# label cluster): coordinator and two workers on a bridge, CURVE on, a link
# taken down and brought back, a tbf-limited link. Needs root and `ip netns`;
# without them it exits 77, which ctest reports as skipped.
if(TARGET photonfarm AND TARGET photonfarm-worker)
  add_test(NAME deploy
           COMMAND bash ${CMAKE_SOURCE_DIR}/tests/test_deploy.sh $<TARGET_FILE:photonfarm>
                   $<TARGET_FILE:photonfarm-worker> ${CMAKE_BINARY_DIR}
           WORKING_DIRECTORY ${CMAKE_SOURCE_DIR})
  set_tests_properties(deploy PROPERTIES LABELS "unit" TIMEOUT 600)

  add_test(NAME cluster
           COMMAND bash ${CMAKE_SOURCE_DIR}/tests/test_cluster.sh $<TARGET_FILE:photonfarm>
                   $<TARGET_FILE:photonfarm-worker>
           WORKING_DIRECTORY ${CMAKE_SOURCE_DIR})
  set_tests_properties(cluster PROPERTIES LABELS "cluster" TIMEOUT 900 SKIP_RETURN_CODE 77
                       RUN_SERIAL TRUE)
else()
  message(STATUS "deploy and cluster tests skipped: no photonfarm-worker target yet")
endif()
