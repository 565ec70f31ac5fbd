# examples/04_embree_host.cpp (issue #22): a host's Embree geometry and
# cellray's volume along the same rays, depth-correct. Included by
# tests/cli/CMakeLists.txt when the example is built (Embree 3 found); uses
# cli_test and cli_script (P: png_check, O: the output folder).
#
# --layers writes the geometry alone and the volume alone (its rays not
# ended); png_check --occluded then wants pixels where the volume alone is
# clearly there but the composite equals the geometry (the pillar in front
# of it), pixels the volume changes, and none changed where it is empty.
# Without depth the layer is drawn over the pillar: no pixel hidden, the
# check fails (seen: DVR with rays to +inf instead of Embree's t; the
# isosurface with neither depth_in nor the depth_out < Embree's t test; with
# either one alone an opaque surface is still right).
set(embree_host $<TARGET_FILE:example_04_embree_host>)

cli_test("example 04_embree_host writes a PNG" --png ${out}/04_embree_host.png 640 480
  0 any ${embree_host} ${out}/04_embree_host.png)
cli_script("04_embree_host: DVR ends at Embree's hits (hidden behind the pillar, over the rest)" "
  ${embree_host} --layers $O/embree_dvr.png
  $P --occluded $O/embree_dvr.geometry.png $O/embree_dvr.volume.png $O/embree_dvr.png 1000 5000")
cli_script("04_embree_host: the opaque isosurface and Embree's geometry, the nearer wins" "
  ${embree_host} --iso --layers $O/embree_iso.png
  $P --occluded $O/embree_iso.geometry.png $O/embree_iso.volume.png $O/embree_iso.png 1000 10000")
