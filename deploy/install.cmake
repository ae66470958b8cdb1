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

set(SPRINGFIT_DOC_DIR ${CMAKE_INSTALL_DATADIR}/doc/springfit)
install(FILES README.md DESTINATION ${SPRINGFIT_DOC_DIR})
install(FILES proto/EVAL.md proto/IMPORT.md proto/MODEL.md proto/RPC.md proto/RUN.md
              proto/SCENE.md proto/scene.schema.json
        DESTINATION ${SPRINGFIT_DOC_DIR})
install(FILES deploy/README.md DESTINATION ${SPRINGFIT_DOC_DIR}/deploy)
install(FILES docs/ARCHITECTURE.md DESTINATION ${SPRINGFIT_DOC_DIR}/docs)
install(FILES deploy/springfitd.env deploy/springfitd-worker.env
        DESTINATION ${SPRINGFIT_DOC_DIR}/examples)
install(DIRECTORY examples/ DESTINATION ${CMAKE_INSTALL_DATADIR}/springfit/examples)
