# Installing mcdenoise: `cmake --install build [--prefix P]` (DESTDIR honoured) and
# `cpack -G DEB` (a .deb of the same files; .ci/package builds one for /usr).
#
#   <prefix>/bin/mcdntool
#   <prefix>/<libdir>/libmcdenoise.so.*          the library: every op
#   <prefix>/<libdir>/mcdenoise/mcdn.imageio.so  the OIIO format plugin (OIIO_LIBRARY_PATH)
#   <prefix>/<libdir>/cmake/mcdenoise/           find_package(mcdenoise) -> mcdenoise::mcdenoise
#   <prefix>/<libdir>/pkgconfig/mcdenoise.pc
#   <prefix>/include/mcdn/*.h
#   <prefix>/share/mcdenoise/{models,ocio}       found relative to the library's own file
#   <python dir>/mcdenoise/                      `import mcdenoise` for /usr/bin/python3
#                                                (_mcdenoise.*.so, __init__.py, shot.py)
#
# Every binary finds the library through a relative RPATH ($ORIGIN), and the library finds
# its data relative to itself, so an installed tree works wherever it is copied.
include(CMakePackageConfigHelpers)

# The build tree's share/mcdenoise: links to the source tree's models/ and ocio/, so that the
# binaries in build/ run exactly as installed ones do (with the same relative lookup).
set(MCDN_BUILD_DATA_DIR ${CMAKE_BINARY_DIR}/${CMAKE_INSTALL_DATADIR}/mcdenoise)
file(MAKE_DIRECTORY ${MCDN_BUILD_DATA_DIR})
foreach(dir models ocio)
  if(NOT EXISTS ${MCDN_BUILD_DATA_DIR}/${dir})
    file(CREATE_LINK ${CMAKE_SOURCE_DIR}/${dir} ${MCDN_BUILD_DATA_DIR}/${dir} SYMBOLIC)
  endif()
endforeach()

install(TARGETS mcdenoise EXPORT mcdenoiseTargets
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(DIRECTORY ${CMAKE_SOURCE_DIR}/lib/include/mcdn DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
        FILES_MATCHING PATTERN "*.h")
install(FILES ${CMAKE_SOURCE_DIR}/models/kpcn.mcdnw ${CMAKE_SOURCE_DIR}/models/kpcn_can.mcdnw
              ${CMAKE_SOURCE_DIR}/models/mix.mcdnw
              ${CMAKE_SOURCE_DIR}/models/mix_cnn.mcdnw ${CMAKE_SOURCE_DIR}/models/mix_oidn.mcdnw
        DESTINATION ${CMAKE_INSTALL_DATADIR}/mcdenoise/models)
install(FILES ${CMAKE_SOURCE_DIR}/ocio/config.ocio
        DESTINATION ${CMAKE_INSTALL_DATADIR}/mcdenoise/ocio)

# find_package(mcdenoise): the library's public dependency is OpenImageIO (its headers take
# ImageBufs), found the way this project finds it (pkg-config: Debian's OIIO CMake config
# names a missing OpenCV folder).
set(MCDN_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/mcdenoise)
install(EXPORT mcdenoiseTargets NAMESPACE mcdenoise:: DESTINATION ${MCDN_CMAKE_DIR})
configure_package_config_file(${CMAKE_SOURCE_DIR}/cmake/mcdenoiseConfig.cmake.in
  ${CMAKE_BINARY_DIR}/cmake/mcdenoiseConfig.cmake INSTALL_DESTINATION ${MCDN_CMAKE_DIR})
write_basic_package_version_file(${CMAKE_BINARY_DIR}/cmake/mcdenoiseConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_BINARY_DIR}/cmake/mcdenoiseConfig.cmake
              ${CMAKE_BINARY_DIR}/cmake/mcdenoiseConfigVersion.cmake
        DESTINATION ${MCDN_CMAKE_DIR})
# The .pc names its prefix relative to its own folder, so it holds under --prefix and DESTDIR.
file(RELATIVE_PATH MCDN_PC_TO_PREFIX ${CMAKE_INSTALL_FULL_LIBDIR}/pkgconfig ${CMAKE_INSTALL_PREFIX})
configure_file(${CMAKE_SOURCE_DIR}/cmake/mcdenoise.pc.in ${CMAKE_BINARY_DIR}/mcdenoise.pc @ONLY)
install(FILES ${CMAKE_BINARY_DIR}/mcdenoise.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)

# A Debian package of everything above: cpack -G DEB in a build configured for /usr
# (.ci/package). Depends come from the binaries' linked libraries (dpkg-shlibdeps), plus
# what the Python module and the plugin are used with.
set(CPACK_PACKAGE_NAME mcdenoise)
set(CPACK_PACKAGE_VENDOR mcdenoise)
set(CPACK_PACKAGE_CONTACT "mcdenoise developers")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "${PROJECT_DESCRIPTION}")
set(CPACK_PACKAGE_DESCRIPTION
  "NFOR, KPCN and the progressive mix (SURE, t-test) as OpenImageIO ImageBufAlgo-style ops:\n"
  "the mcdntool command line, an OIIO format plugin for oiiotool and a Python module.")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION graphics)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_DEPENDS "python3-openimageio")
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS "openimageio-tools")
# python3 -m mcdenoise.shot runs a shot's frames on Dask.
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "python3-distributed")
set(CPACK_STRIP_FILES ON)
set(CPACK_PACKAGE_INSTALL_DIRECTORY mcdenoise)
include(CPack)
