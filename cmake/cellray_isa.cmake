# cellray_add_isa_units(<target> [ISAS <isa>...] [SOURCES <file>...] [OPTIONS <opt>...])
#
# Compiles cellray's ISA unit (every entry point) once per ISA -- SSE4.2,
# AVX2+FMA, AVX-512 -- each with that ISA's flags and -DCELLRAY_ISA_UNIT=0|1|2,
# and links the objects into <target>, so `cellray::dispatch` can pick the
# best ISA at run time. ISAS picks a subset of sse4, avx2, avx512 (default:
# the CELLRAY_ISAS cache variable, all three): each ISA costs one compile of
# every entry point and its share of the binary. The target (PUBLIC) and its
# ISA units get -DCELLRAY_ISA_COMPILED_MASK, so `best_isa()` only picks a
# compiled ISA and dispatching to another one throws. Link all of a
# program's cellray code with the same subset. SOURCES adds more files
# compiled the same way (e.g. test-only instantiations); OPTIONS adds compile
# options to the ISA objects (e.g. warnings). The target keeps baseline flags.

if(NOT DEFINED CELLRAY_ISA_UNIT_SOURCE)  # the installed config sets it
  set(CELLRAY_ISA_UNIT_SOURCE "${CMAKE_CURRENT_LIST_DIR}/../include/cellray/dispatch/isa_unit.cpp")
endif()

set(CELLRAY_ISA_FLAGS_0 "-msse4.2" CACHE INTERNAL "")
set(CELLRAY_ISA_FLAGS_1 "-msse4.2;-mavx2;-mfma" CACHE INTERNAL "")
set(CELLRAY_ISA_FLAGS_2 "-msse4.2;-mavx2;-mfma;-mavx512f;-mavx512cd;-mavx512dq;-mavx512bw" CACHE INTERNAL "")
# GCC 12 warns falsely about '__Y' in avx512fintrin.h at -O1 and above; these
# must come after any -Wall, so they are applied last (see below).
set(CELLRAY_ISA_LATE_FLAGS_2 "$<$<CXX_COMPILER_ID:GNU>:-Wno-uninitialized;-Wno-maybe-uninitialized>" CACHE INTERNAL "")
# GCC 12.2 at -O2 dropped the results of a width-1 sub-traversal called from
# an AVX2 packet traversal (its writes to the query object were not seen by
# the caller); -fno-ipa-modref, -O1, clang, ASan or UBSan all gave the right
# answer. Not reduced to a minimal case yet; kept off in every ISA unit.
set(CELLRAY_ISA_GCC_SAFETY "$<$<CXX_COMPILER_ID:GNU>:-fno-ipa-modref>" CACHE INTERNAL "")
set(CELLRAY_ISA_NAMES sse4 avx2 avx512 CACHE INTERNAL "")
set(CELLRAY_ISAS "sse4;avx2;avx512" CACHE STRING "ISA units cellray_add_isa_units() compiles by default (sse4, avx2, avx512)")

function(cellray_add_isa_units target)
  cmake_parse_arguments(ARG "NO_LIBRARY_UNIT" "" "ISAS;SOURCES;OPTIONS" ${ARGN})
  set(sources ${ARG_SOURCES})
  if(NOT ARG_NO_LIBRARY_UNIT)
    list(APPEND sources "${CELLRAY_ISA_UNIT_SOURCE}")
  endif()
  set(isas ${ARG_ISAS})
  if(NOT isas)
    set(isas ${CELLRAY_ISAS})
  endif()
  set(mask 0)
  foreach(isa ${isas})
    list(FIND CELLRAY_ISA_NAMES "${isa}" i)
    if(i LESS 0)
      message(FATAL_ERROR "cellray_add_isa_units(${target}): unknown ISA '${isa}' (expected sse4, avx2, avx512)")
    endif()
    math(EXPR mask "${mask} | (1 << ${i})")
  endforeach()
  if(mask EQUAL 0)
    message(FATAL_ERROR "cellray_add_isa_units(${target}): no ISA selected (CELLRAY_ISAS is empty)")
  endif()
  target_compile_definitions(${target} PUBLIC CELLRAY_ISA_COMPILED_MASK=${mask})
  foreach(i 0 1 2)
    math(EXPR bit "(${mask} >> ${i}) & 1")
    if(bit EQUAL 0)
      continue()
    endif()
    list(GET CELLRAY_ISA_NAMES ${i} isa)
    set(obj ${target}_isa_${isa})
    add_library(${obj} OBJECT ${sources})
    target_link_libraries(${obj} PRIVATE cellray::cellray)
    target_compile_definitions(${obj} PRIVATE CELLRAY_ISA_UNIT=${i} CELLRAY_ISA_COMPILED_MASK=${mask})
    target_compile_options(${obj} PRIVATE ${CELLRAY_ISA_FLAGS_${i}})
    target_compile_options(${obj} PRIVATE ${ARG_OPTIONS} ${CELLRAY_ISA_LATE_FLAGS_${i}} ${CELLRAY_ISA_GCC_SAFETY})
    target_sources(${target} PRIVATE $<TARGET_OBJECTS:${obj}>)
  endforeach()
endfunction()
