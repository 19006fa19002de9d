# docs/cli.md must equal `areomap cli-reference` (the reference is generated from the CLI's own
# definitions). Called with -DAREOMAP=<binary> -DDOC=<docs/cli.md>.
execute_process(COMMAND ${AREOMAP} cli-reference OUTPUT_VARIABLE generated RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "areomap cli-reference failed (exit ${rc})")
endif()
file(READ ${DOC} committed)
if(NOT generated STREQUAL committed)
  message(FATAL_ERROR "${DOC} is out of date with the CLI: regenerate it with\n"
                      "  ${AREOMAP} cli-reference > ${DOC}")
endif()
