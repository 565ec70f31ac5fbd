# Clip planes and boxes, smooth normals and colouring by another array
# (issue #25) from the command line: each against the reference renderer
# with the same flags, in world units on a moved mesh too. Included by
# tests/cli/CMakeLists.txt (cli_test, ${render}, ${out}); cli_script comes
# from hostile.cmake.

set(ccdata ${CMAKE_CURRENT_SOURCE_DIR}/data)

cli_test("iso normals are smooth by default (12 bytes a vertex)" 0 [=["normals":"smooth","gradients_ms":[0-9.e+-]+,"gradients_bytes":324,]=]
  ${render} ${ccdata}/block.vtk --size 32x24 --stats -o ${out}/normals_default.png)
cli_script("smooth and flat normals draw different pictures, each as the reference does" "
  $R ${ccdata}/block.vtk --iso 0.9 --size 64x48 -o $O/smooth.png
  $R ${ccdata}/block.vtk --iso 0.9 --size 64x48 --normals flat -o $O/flat.png
  if $P --compare $O/smooth.png $O/flat.png 0 4; then echo 'expected different images'; exit 1; fi
  $R ${ccdata}/block.vtk --iso 0.9 --size 64x48 --reference -o $O/smooth_ref.png
  $P --compare $O/smooth.png $O/smooth_ref.png 15")
# The gradients are computed beside the BVH build only when the build's
# array is the one rendered: a time step's normals are its own array's.
cli_script("a time step's smooth normals are those of its own array" "
  $R --cells 5000 --time-step 1 --size 64x48 -o $O/step_normals.png
  $R --cells 5000 --array field_t1 --size 64x48 -o $O/step_normals_built.png
  $P --compare $O/step_normals.png $O/step_normals_built.png 0 1")
foreach(mode iso dvr)
  cli_script("--clip and --clip-box (${mode}) render as the reference does" "
    $R ${ccdata}/block.vtk --mode ${mode} --clip 1,1,1,1,0.3,0.2 --clip-caps --size 64x48 -o $O/clip_${mode}.png
    $R ${ccdata}/block.vtk --mode ${mode} --clip 1,1,1,1,0.3,0.2 --clip-caps --size 64x48 --reference -o $O/clip_${mode}_ref.png
    $P --compare $O/clip_${mode}.png $O/clip_${mode}_ref.png 30
    $R ${ccdata}/block.vtk --mode ${mode} --size 64x48 -o $O/noclip_${mode}.png
    if $P --compare $O/clip_${mode}.png $O/noclip_${mode}.png 100; then echo 'expected different images'; exit 1; fi
    $R ${ccdata}/block.vtk --mode ${mode} --clip-box 0,0,0,1.2,1.5,2 --size 64x48 -o $O/box_${mode}.png
    $R ${ccdata}/block.vtk --mode ${mode} --clip-box 0,0,0,1.2,1.5,2 --size 64x48 --reference -o $O/box_${mode}_ref.png
    $P --compare $O/box_${mode}.png $O/box_${mode}_ref.png 30")
endforeach()
cli_script("--clip is in world units on a moved mesh" "
  $R ${ccdata}/block.vtk --clip 1,1,1,1,0.3,0.2 --clip-caps --size 64x48 -o $O/clip_world_ref.png
  $R ${ccdata}/block_offset_1e7.vtk --clip 10000001,10000001,10000001,1,0.3,0.2 --clip-caps --size 64x48 -o $O/clip_world.png
  $P --compare $O/clip_world.png $O/clip_world_ref.png 30")
cli_script("--color-by colours the isosurfaces by another array, as the reference does" "
  $R --cells 3000 --color-by field_t1 --color-map viridis --size 64x48 -o $O/colorby.png
  $R --cells 3000 --color-by field_t1 --color-map viridis --size 64x48 --reference -o $O/colorby_ref.png
  $P --compare $O/colorby.png $O/colorby_ref.png 30
  $R --cells 3000 --size 64x48 -o $O/nocolor.png
  if $P --compare $O/colorby.png $O/nocolor.png 100; then echo 'expected different images'; exit 1; fi")
cli_test("--clip with five numbers exits 2" 2 [=[--clip: expected X,Y,Z,NX,NY,NZ]=]
  ${render} --cells 1000 --clip 1,2,3,4,5 -o ${out}/clipbad.png)
cli_test("--clip with a zero normal exits 2" 2 [=[normal of '0,0,0,0,0,0' is zero]=]
  ${render} --cells 1000 --clip 0,0,0,0,0,0 -o ${out}/clipzero.png)
cli_test("--clip-box with lo > hi exits 2" 2 [=[--clip-box: expected]=]
  ${render} --cells 1000 --clip-box 1,0,0,0,1,1 -o ${out}/boxbad.png)
cli_test("--clip-caps without a clip exits 2" 2 [=[--clip-caps: give --clip or --clip-box]=]
  ${render} --cells 1000 --clip-caps -o ${out}/capsbad.png)
cli_test("--color-by an unknown array exits 2 naming the arrays" 2 [=[--color-by: default scene has no point array 'nope']=]
  ${render} --cells 1000 --color-by nope -o ${out}/colorbad.png)
