# `cmake --install build [--prefix P]` (default prefix /usr/local): the two programs, the
# systemd units (with the installed programs' paths), their settings files as examples, the
# protocol and format documents, and the example scenes. The README's "Install" says where
# each goes and what is left to do by hand (the settings under /etc, the token).
include(GNUInstallDirs)

install(TARGETS springfit springfitd RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})

# The units in deploy/ name /usr/local (the default prefix): rewritten for the prefix given,
# at install time, so that `--prefix` at install time counts too.
set(SPRINGFIT_UNIT_DIR lib/systemd/system)  # systemd searches <prefix>/lib/systemd/system
foreach(unit springfitd.service springfitd-worker.service)
  install(CODE "
    set(prefix \"\${CMAKE_INSTALL_PREFIX}\")
    file(READ \"${PROJECT_SOURCE_DIR}/deploy/${unit}\" text)
    string(REPLACE \"/usr/local/bin/\" \"\${prefix}/${CMAKE_INSTALL_BINDIR}/\" text \"\${text}\")
    string(REPLACE \"/usr/local/share/doc/springfit/\" \"\${prefix}/${CMAKE_INSTALL_DATADIR}/doc/springfit/\" text \"\${text}\")
    file(MAKE_DIRECTORY \"\$ENV{DESTDIR}\${prefix}/${SPRINGFIT_UNIT_DIR}\")
    file(WRITE \"\$ENV{DESTDIR}\${prefix}/${SPRINGFIT_UNIT_DIR}/${unit}\" \"\${text}\")
    message(STATUS \"Installing: \$ENV{DESTDIR}\${prefix}/${SPRINGFIT_UNIT_DIR}/${unit}\")
  ")
endforeach()

# The documents keep the repository's layout under the doc directory, so that every link in the
# installed README (proto/RPC.md, docs/ARCHITECTURE.md, ...) finds its file (install_test.sh
# follows them all).
set(SPRINGFIT_DOC_DIR ${CMAKE_INSTALL_DATADIR}/doc/springfit)
install(FILES README.md DESTINATION ${SPRINGFIT_DOC_DIR})
install(FILES proto/EVAL.md proto/IMPORT.md proto/MODEL.md proto/RPC.md proto/RUN.md
              proto/SCENE.md proto/scene.schema.json
        DESTINATION ${SPRINGFIT_DOC_DIR}/proto)
install(FILES deploy/README.md DESTINATION ${SPRINGFIT_DOC_DIR}/deploy)
install(FILES docs/ARCHITECTURE.md docs/dashboard-job.png DESTINATION ${SPRINGFIT_DOC_DIR}/docs)
install(FILES server/README.md DESTINATION ${SPRINGFIT_DOC_DIR}/server)
install(FILES bench/RESULTS.md DESTINATION ${SPRINGFIT_DOC_DIR}/bench)
install(PROGRAMS scripts/main-job.sh DESTINATION ${SPRINGFIT_DOC_DIR}/scripts)
install(FILES python/README.md DESTINATION ${SPRINGFIT_DOC_DIR}/python)
install(FILES deploy/springfitd.env deploy/springfitd-worker.env
        DESTINATION ${SPRINGFIT_DOC_DIR}/examples)
install(DIRECTORY examples/ DESTINATION ${CMAKE_INSTALL_DATADIR}/springfit/examples)

# The Python client (python/), where the system's Python finds a package installed under the
# prefix: Debian's python3 searches <prefix>/lib/python3.X/dist-packages for /usr/local, and
# lib/python3/dist-packages for /usr (its own packages' place). SPRINGFIT_PYTHON_DIR overrides
# it (relative to the prefix). `pip install ./python` installs the same package into a venv.
find_package(Python3 COMPONENTS Interpreter)
if(Python3_FOUND)
  set(springfit_python_default lib/python3.${Python3_VERSION_MINOR}/dist-packages)
else()
  set(springfit_python_default lib/python3/dist-packages)
endif()
set(SPRINGFIT_PYTHON_DIR "${springfit_python_default}" CACHE STRING
    "Where cmake --install puts the Python client, relative to the prefix")
install(DIRECTORY python/springfit_client DESTINATION ${SPRINGFIT_PYTHON_DIR}
        PATTERN "__pycache__" EXCLUDE)
