# Framing, colour legend and turntables of cellray-render (issue #25, items
# 4-6). Included at the end of tests/cli/CMakeLists.txt; uses cli_test(),
# and cli_script() with R (renderer), P (png_check), O (output folder) from
# hostile.cmake.

set(pdata ${CMAKE_CURRENT_SOURCE_DIR}/data)
# A 0.5 x 1 x 3 box drawn opaque: its silhouette is its projected bounds.
# The old bounding-sphere fit drew it at 59-61% of the shorter side.
set(box "${pdata}/long_box.vtk --mode dvr --tf ${pdata}/opaque_preset.json")

# Framing: the projected bounds span 90% of the shorter side, centred.
foreach(size 160x90 100x100 90x160)
  cli_script("framing: the default view spans 80-95% of the shorter side, centred, at ${size}" "
    $R ${box} --size ${size} -o $O/frame_${size}.png
    $P --extent $O/frame_${size}.png 0.80 0.95")
endforeach()
cli_script("framing: --zoom 0.5 halves the drawn extent" "
  $R ${box} --size 120x90 --zoom 0.5 -o $O/frame_zoom.png
  $P --extent $O/frame_zoom.png 0.40 0.48")
cli_script("framing: --azimuth and --elevation turn the view, which stays framed" "
  $R ${box} --size 120x90 -o $O/frame_plain.png
  $R ${box} --size 120x90 --azimuth 90 -o $O/frame_az90.png
  $R ${box} --size 120x90 --azimuth 360 -o $O/frame_az360.png
  $R ${box} --size 120x90 --elevation 90 -o $O/frame_el90.png
  $P --extent $O/frame_az90.png 0.80 0.95
  $P --extent $O/frame_el90.png 0.80 0.95
  if $P --compare $O/frame_plain.png $O/frame_az90.png 100; then echo 'FAIL: --azimuth 90 changed little'; exit 1; fi
  if $P --compare $O/frame_plain.png $O/frame_el90.png 100; then echo 'FAIL: --elevation 90 changed little'; exit 1; fi
  $P --compare $O/frame_plain.png $O/frame_az360.png 4")
cli_script("framing: --eye wins over --zoom and --azimuth" "
  $R ${box} --size 64x48 --eye 3,2,6 -o $O/frame_eye.png
  $R ${box} --size 64x48 --eye 3,2,6 --zoom 3 --azimuth 40 --elevation 10 -o $O/frame_eye2.png
  $P --compare $O/frame_eye.png $O/frame_eye2.png 0 0")
cli_test("--zoom 0 exits 2" 2 [=[--zoom]=] ${render} --cells 1000 --zoom 0 -o ${out}/zoom0.png)

# Legend and title: new pixels only where they are drawn, nothing else changed.
cli_script("--legend (iso) draws into the right part of the image only" "
  $R ${real}/vtk-data/post.vtk --size 200x150 -o $O/legend_plain.png
  $R ${real}/vtk-data/post.vtk --size 200x150 --legend -o $O/legend_iso.png
  $P --diff-within $O/legend_plain.png $O/legend_iso.png 0.55 0.1 1 0.95 300")
cli_script("--legend (DVR, transparent background) draws into the right part only" "
  $R ${real}/vtk-data/hexa.vtk --mode dvr --background transparent --size 200x150 -o $O/legend_dvr_plain.png
  $R ${real}/vtk-data/hexa.vtk --mode dvr --background transparent --size 200x150 --legend -o $O/legend_dvr.png
  $P --diff-within $O/legend_dvr_plain.png $O/legend_dvr.png 0.55 0.1 1 0.95 300")
cli_script("--title draws into the top of the image only" "
  $R ${real}/vtk-data/post.vtk --size 200x150 -o $O/title_plain.png
  $R ${real}/vtk-data/post.vtk --size 200x150 --title 'post.vtk: Pressure' -o $O/title.png
  $P --diff-within $O/title_plain.png $O/title.png 0 0 1 0.2 100")
cli_test("--legend with a missing font exits 3 and names it" --absent ${out}/nofont.png
  3 [=[font file /nonexistent/NoSuchFont\.ttf]=]
  ${render} --cells 1000 --legend --font /nonexistent/NoSuchFont.ttf -o ${out}/nofont.png)
cli_test("--font naming a device exits 3 at once (it used to read /dev/zero forever)" --absent ${out}/devfont.png
  3 [=[font file /dev/zero: is a device, not a regular font file]=]
  timeout 60 ${render} --cells 1000 --title hi --font /dev/zero -o ${out}/devfont.png)
# 100 KB of title: fitting it to the image measured every prefix anew (over
# a minute); now one pass.
cli_test("a 100 KB --title is cut to the image's width at once" --png ${out}/longtitle.png 64 48 0 any
  timeout 60 sh -c [=[exec "$0" --cells 1000 --size 64x48 --title "$(head -c 100000 /dev/zero | tr '\0' x)" -o "$1"]=]
  ${render} ${out}/longtitle.png)

# Turntables: N numbered files, every view framed and centred, views
# differ; one view is the plain render (the default view's distance is the
# largest fit over the views, so --orbit 1, or a given --eye).
cli_script("--orbit 1 renders the plain render to spin1_0000.png" "
  $R ${box} --size 64x48 -o $O/spin1_plain.png
  $R ${box} --size 64x48 --orbit 1 -o $O/spin1.png
  $P --compare $O/spin1_plain.png $O/spin1_0000.png 0 0")
cli_script("--orbit 4 writes spin_0000..0003, all framed, views differ" "
  rm -f $O/spin_*.png $O/spin.png
  $R ${box} --size 64x48 --orbit 4 -o $O/spin.png
  test ! -e $O/spin.png && test ! -e $O/spin_0004.png
  for k in 0 1 2 3; do $P --extent $O/spin_000$k.png 0.5 0.95; done
  for a in 0 1 2 3; do for b in 0 1 2 3; do
    [ $a -lt $b ] || continue
    if $P --compare $O/spin_000$a.png $O/spin_000$b.png 20; then echo \"FAIL: views $a and $b alike\"; exit 1; fi
  done; done")
cli_script("--orbit 4 with --eye: view 2 is the eye turned 180 degrees about +y" "
  $R ${box} --size 64x48 --eye 3,2,6 --orbit 4 -o $O/turn.png
  $R ${box} --size 64x48 --eye 3,2,6 -o $O/turn_0.png
  $R ${box} --size 64x48 --eye=-2.5,2,-3 -o $O/turn_180.png
  $P --compare $O/turn_0.png $O/turn_0000.png 0 0
  $P --compare $O/turn_180.png $O/turn_0002.png 4")
cli_script("--orbit on a moved mesh renders the plain mesh's views" "
  $R ${hostile}/block.vtk --size 64x48 --orbit 3 -o $O/orbit_ref.png
  $R ${hostile}/block_offset_1e7.vtk --size 64x48 --orbit 3 -o $O/orbit_moved.png
  for k in 0 1 2; do $P --compare $O/orbit_moved_000$k.png $O/orbit_ref_000$k.png 30; done")
cli_test("--orbit with --frames 2 exits 2" 2 [=[--orbit with --frames 2]=]
  ${render} --cells 1000 --orbit 3 --frames 2 -o ${out}/orbit_frames.png)
cli_test("--help describes the orbit's file names" 0 [=[spin_0000\.png]=] ${render} --help)
