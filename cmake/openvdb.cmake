# cmake/openvdb.cmake — finds OpenVDB (the engine's closed-mesh interiors,
# grid/src/mesh_interior.cpp, and `voxvis export --vdb`, vdb/), for the main
# build and the fuzz build alike. Debian ships OpenVDB's find module rather
# than a package configuration. The module sets BUILD_SHARED_LIBS for its own
# sake; unset here, the project's libraries stay static.
list(APPEND CMAKE_MODULE_PATH /usr/lib/${CMAKE_LIBRARY_ARCHITECTURE}/cmake/OpenVDB)
find_package(OpenVDB REQUIRED)
unset(BUILD_SHARED_LIBS)
