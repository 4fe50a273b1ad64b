# Writes OUTPUT, a header defining LINEBAKE_SOURCE_REVISION: the git commit the build's sources
# are at ("fda8cce1a2"), "+modified" when tracked files differ from it, "unknown" outside a git
# checkout. Run at every build (tools/CMakeLists.txt); the file is rewritten only when the text
# changes, so a build of the same commit compiles nothing again. `linebake version` and the
# measurements of `bench render` carry it: a figure names the code it came from.
#   cmake -DSOURCE_DIR=... -DOUTPUT=... -P source_revision.cmake
set(revision unknown)
find_package(Git QUIET)
if(GIT_FOUND)
  execute_process(COMMAND "${GIT_EXECUTABLE}" -C "${SOURCE_DIR}" rev-parse --short=10 HEAD
                  OUTPUT_VARIABLE commit OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET
                  RESULT_VARIABLE failed)
  if(NOT failed AND commit)
    set(revision "${commit}")
    execute_process(COMMAND "${GIT_EXECUTABLE}" -C "${SOURCE_DIR}" status --porcelain --untracked-files=no
                    OUTPUT_VARIABLE changes OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
    if(changes)
      string(APPEND revision "+modified")
    endif()
  endif()
endif()
set(text "#pragma once\n#define LINEBAKE_SOURCE_REVISION \"${revision}\"\n")
if(EXISTS "${OUTPUT}")
  file(READ "${OUTPUT}" old)
endif()
if(NOT old STREQUAL text)
  file(WRITE "${OUTPUT}" "${text}")
endif()
