# `cmake --install BUILD --prefix P` and `cpack -G DEB` (docs/development.md, "Install"):
#   P/bin/octshape                     the tool
#   P/share/man/man1/octshape.1        its manual page, made from --help at build time (app/)
#   P/share/doc/octshape/              README, LICENSE, CITATION.cff and docs/
#   P/share/octshape/workflow/         the Snakemake workflow (docs/cohort.md)
#   P/include/octshape/{mesh/*.h,error.h,version.h}, P/lib/liboctshape_{mesh,base}.a and
#   P/lib/cmake/octshape/              libmesh for other CMake projects:
#                                      find_package(octshape CONFIG) -> octshape::mesh
include(CMakePackageConfigHelpers)

install(TARGETS octshape_mesh octshape_base EXPORT octshapeTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/libmesh/include/octshape/mesh
  DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/octshape COMPONENT dev)
install(FILES ${PROJECT_SOURCE_DIR}/base/include/octshape/error.h
              ${PROJECT_BINARY_DIR}/generated/octshape/version.h
  DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/octshape COMPONENT dev)
set(_cmake_dir ${CMAKE_INSTALL_LIBDIR}/cmake/octshape)
install(EXPORT octshapeTargets NAMESPACE octshape:: DESTINATION ${_cmake_dir} COMPONENT dev)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/octshapeConfig.cmake.in
  ${PROJECT_BINARY_DIR}/octshapeConfig.cmake INSTALL_DESTINATION ${_cmake_dir})
# 0.x: a minor version may change the library's interface (docs/versioning.md).
write_basic_package_version_file(${PROJECT_BINARY_DIR}/octshapeConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/octshapeConfig.cmake
              ${PROJECT_BINARY_DIR}/octshapeConfigVersion.cmake
  DESTINATION ${_cmake_dir} COMPONENT dev)

install(FILES ${PROJECT_SOURCE_DIR}/README.md ${PROJECT_SOURCE_DIR}/LICENSE
              ${PROJECT_SOURCE_DIR}/CITATION.cff
  DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT tool)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT tool)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/workflow/
  DESTINATION ${CMAKE_INSTALL_DATADIR}/octshape/workflow COMPONENT tool)

# The Debian package: one package with the tool and libmesh's development files. Its
# dependencies are computed by dpkg-shlibdeps from the libraries the executable loads (the
# Debian runtime packages, e.g. libvtk9.1, libopencv-core406), never listed by hand.
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME octshape)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_VENDOR "the octshape authors")
set(CPACK_PACKAGE_CONTACT "the octshape authors")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
  "3-D shape parameters of the fovea and optic nerve head from OCT exports")
set(CPACK_PACKAGE_DESCRIPTION
  "octshape reads retinal OCT exports (Heidelberg Spectralis .vol and XML, Iowa surfaces XML) and computes the fovea's cubic-Bezier (CuBe) shape parameters and the optic nerve head's BMO, volumes and minimum rim width, per eye and over cohorts, with provenance in every output. It includes libmesh, a library of triangle-mesh denoisers (RoFi, ENVT, bilateral normal filtering), usable from CMake with find_package(octshape CONFIG).")
set(CPACK_RESOURCE_FILE_LICENSE ${PROJECT_SOURCE_DIR}/LICENSE)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# Only for building against libmesh (its headers include Eigen's): a suggestion, not a need.
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "libeigen3-dev, cmake")
include(CPack)
