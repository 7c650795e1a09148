# cmake/install.cmake: what `cmake --install build --prefix DIR` puts where
# (deploy/install.sh runs it). Included from the root CMakeLists.txt after
# the targets are defined; deploy/install.sh also passes it as
# CMAKE_PROJECT_INCLUDE to a tree whose CMakeLists.txt does not include it
# yet, which is why the executables are named with generator expressions
# (resolved when the build system is generated, once every target exists)
# rather than with install(TARGETS), and why the file guards against a
# second inclusion.
#
#   bin/photonfarm, bin/photonfarm-worker
#   share/doc/photonfarm/        README.md and docs/*.md (cluster.md, farm.md, ...)
#   share/photonfarm/scenes/     the shipped scenes (the demo renders cornell-spheres)
#   share/photonfarm/deploy/     the systemd units, the Slurm script, the Kubernetes
#                                manifests and the container file (docs/cluster.md)
include_guard(GLOBAL)
include(GNUInstallDirs)

install(PROGRAMS $<TARGET_FILE:photonfarm> $<TARGET_FILE:photonfarm-worker>
        DESTINATION ${CMAKE_INSTALL_BINDIR})
install(FILES ${CMAKE_SOURCE_DIR}/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(DIRECTORY ${CMAKE_SOURCE_DIR}/docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR}
        FILES_MATCHING PATTERN "*.md" PATTERN "*.png")
install(DIRECTORY ${CMAKE_SOURCE_DIR}/scenes/ DESTINATION ${CMAKE_INSTALL_DATADIR}/photonfarm/scenes)
install(DIRECTORY ${CMAKE_SOURCE_DIR}/deploy/systemd ${CMAKE_SOURCE_DIR}/deploy/slurm
                  ${CMAKE_SOURCE_DIR}/deploy/k8s ${CMAKE_SOURCE_DIR}/deploy/container
        DESTINATION ${CMAKE_INSTALL_DATADIR}/photonfarm/deploy
        USE_SOURCE_PERMISSIONS)
