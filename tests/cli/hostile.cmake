# Hostile input against cellray-render (issue #24): each case failed before
# it was fixed. Included by tests/cli/CMakeLists.txt, whose cli_test(),
# ${render}, ${out} and ${expect} it uses. Meshes: tests/cli/data/make_hostile.py.

set(hostile ${CMAKE_CURRENT_SOURCE_DIR}/data)
set(png_check $<TARGET_FILE:png_check>)

# cli_script(<name> <shell script>): runs the script with sh -e; R is the
# renderer, P png_check, O the output folder.
function(cli_script name script)
  add_test(NAME "cli: ${name}" COMMAND sh -ec "${script}")
  set_tests_properties("cli: ${name}" PROPERTIES TIMEOUT 120 SKIP_RETURN_CODE 77
    ENVIRONMENT "R=${render};P=${png_check};O=${out};E=${expect};PNG_CHECK=${png_check}")
endfunction()

# 1. +-inf values make their cells invisible, as NaN does and as the reference draws.
foreach(mode iso dvr)
  cli_script("+-inf values (${mode}): the fast image is the NaN one and the reference's" "
    $R ${hostile}/block_inf.vtk --mode ${mode} --iso 0.6,1.1 --size 64x48 -o $O/inf_${mode}.png
    $R ${hostile}/block_nan.vtk --mode ${mode} --iso 0.6,1.1 --size 64x48 -o $O/nan_${mode}.png
    $R ${hostile}/block_inf.vtk --mode ${mode} --iso 0.6,1.1 --size 64x48 --reference -o $O/inf_${mode}_ref.png
    $P --compare $O/inf_${mode}.png $O/nan_${mode}.png 0 0
    $P --compare $O/inf_${mode}.png $O/inf_${mode}_ref.png 30")
endforeach()
# 2. DVR gradient shading next to NaN cells: no black (NaN) pixels.
cli_script("DVR shading next to NaN cells matches the reference (no NaN pixels)" "
  $R ${hostile}/block_nan.vtk --mode dvr --dvr-shading --size 64x48 -o $O/nan_shaded.png
  $R ${hostile}/block_nan.vtk --mode dvr --dvr-shading --size 64x48 --no-march -o $O/nan_shaded_tree.png
  $P --compare $O/nan_shaded.png $O/nan_shaded_tree.png 0 2")
# 4, 5. A FIFO or a directory as input: exit 3 at once, naming it.
cli_script("a FIFO as mesh or --tf exits 3 without blocking" "
  rm -f $O/fifo.vtk $O/fifo.json; mkfifo $O/fifo.vtk $O/fifo.json
  $E 3 'fifo.vtk: is a FIFO' $R $O/fifo.vtk -o $O/fifo.png
  $E 3 'fifo.json: is a FIFO' $R --cells 1000 --mode dvr --tf $O/fifo.json -o $O/fifo.png")
cli_script("a directory as mesh or --tf exits 3 naming it" "
  mkdir -p $O/dir.vtk $O/dir.json $O/dir.png
  $E 3 'dir.vtk: is a directory' $R $O/dir.vtk -o $O/dir_out.png
  $E 3 'dir.json: is a directory' $R --cells 1000 --mode dvr --tf $O/dir.json -o $O/dir_out.png
  $E 3 '-o: .*dir.png is a directory' $R --cells 1000 -o $O/dir.png")
# 6. Failed writes keep the old image.
add_test(NAME "cli: failed image writes exit 3 and keep the old file"
  COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/write_errors.sh ${render} ${out})
# 7. The extension check is the writer's: any case.
cli_test("-o x.PNG writes a PNG" --png ${out}/upper.PNG 40 30 0 any ${render} --cells 2000 --size 40x30 -o ${out}/upper.PNG)
# 8. Coordinates and values near float's limits, far from the origin or tiny
# render the picture of the plain block.
cli_test("the plain block renders" --png ${out}/block.png 64 48 0 any ${render} ${hostile}/block.vtk --size 64x48 -o ${out}/block.png)
foreach(variant scaled_1e-30 scaled_1e30 offset_1e7 huge huge_values)
  cli_script("block_${variant}.vtk renders like the plain block" "
    $R ${hostile}/block.vtk --size 64x48 -o $O/block_ref_${variant}.png
    $R ${hostile}/block_${variant}.vtk --size 64x48 -o $O/block_${variant}.png
    $P --compare $O/block_${variant}.png $O/block_ref_${variant}.png 30
    $R ${hostile}/block.vtk --mode dvr --size 64x48 -o $O/block_dvr_ref_${variant}.png
    $R ${hostile}/block_${variant}.vtk --mode dvr --size 64x48 -o $O/block_dvr_${variant}.png
    $P --compare $O/block_dvr_${variant}.png $O/block_dvr_ref_${variant}.png 30")
endforeach()
cli_script("--eye and --at are world coordinates on a moved mesh" "
  $R ${hostile}/block.vtk --eye 5,4,6 --at 1,1,1 --size 64x48 -o $O/eye_ref.png
  $R ${hostile}/block_offset_1e7.vtk --eye 10000005,10000004,10000006 --at 10000001,10000001,10000001 --size 64x48 -o $O/eye.png
  $P --compare $O/eye.png $O/eye_ref.png 30")
# 9. Exit codes as docs/cli.md says.
cli_test("a cell naming a vertex the file lacks exits 3" --absent ${out}/badidx.png 3 [=[cell 1 uses vertex id 9]=]
  ${render} ${PROJECT_SOURCE_DIR}/tests/data/broken/bad_index.vtk -o ${out}/badidx.png)
cli_test("--tf missing.json exits 3" --absent ${out}/tfmissing.png 3 [=[missing\.json: cannot open transfer function file]=]
  ${render} --cells 1000 --mode dvr --tf ${out}/missing.json -o ${out}/tfmissing.png)
cli_test("an unknown preset exits 2 before the mesh is read" 2 [=[unknown transfer function preset 'no-such-map']=]
  ${render} ${out}/no_such_mesh.vtk --mode dvr --tf no-such-map -o ${out}/tf2.png)
# 10. Smaller ones.
cli_test("--step 0 says so in one short line" 2 [=[^cellray-render: error: --step.{0,100}$]=]
  ${render} --cells 1000 --mode dvr --step 0 -o ${out}/step0.png)
cli_script("a 100 KB --array name is not echoed whole" "
  name=$(head -c 100000 /dev/zero | tr '\\000' a)
  test $(printf %s $name | wc -c) = 100000
  $E 2 '^cellray-render: error: --array: .{0,400}$' $R ${hostile}/block.vtk --array $name -o $O/longname.png")
cli_test("--size 32768x32768 is refused before any work, naming the size" 2 [=[--size 32768x32768]=]
  ${render} --cells 1000 --size 32768x32768 -o ${out}/huge.png)
cli_test("a constant field renders with a warning" 0 [=[warning: point array 's' is constant]=]
  ${render} ${hostile}/block_constant.vtk --size 32x24 -o ${out}/constant.png)
cli_test("an isovalue outside the values renders with a warning" 0 [=[warning: isovalue 9 lies outside]=]
  ${render} ${hostile}/block.vtk --iso 9,1 --size 32x24 -o ${out}/outside.png)
cli_test("a NaN position on a vertex no cell uses is a warning, not an error" --png ${out}/unused.png 64 48
  0 [=[no cell uses]=] ${render} ${hostile}/block_nan_unused_vertex.vtk -v --size 64x48 -o ${out}/unused.png)
# Exit 1: out of memory, saying in which phase (not under ASan, which
# reserves terabytes of address space).
cli_script("out of memory exits 1 naming the phase" "
  $E 1 'error: out of memory while (generating|building|rendering)' sh -c 'ulimit -v 250000; exec $R --cells 8000000 --size 64x48 -o $O/oom.png'")
set_tests_properties("cli: out of memory exits 1 naming the phase" PROPERTIES LABELS no-sanitizer)
