// One ISA unit: compiled once per ISA by cellray_add_isa_units() with
// -DCELLRAY_ISA_UNIT=0|1|2 and that ISA's flags. It instantiates every entry
// point for that ISA; nothing else may be defined here (see dispatch.hpp).

#include <cellray/dispatch/impl.hpp>

namespace cellray {
CELLRAY_INSTANTIATE_ENTRY(CellBoxes)
CELLRAY_INSTANTIATE_ENTRY(CellRanges)
CELLRAY_INSTANTIATE_ENTRY(CellQueries)
CELLRAY_INSTANTIATE_ENTRY(FirstHitEntry)
CELLRAY_INSTANTIATE_ENTRY(SampleEntry)
CELLRAY_INSTANTIATE_ENTRY(ProbeEntry)
CELLRAY_INSTANTIATE_ENTRY(OcclusionEntry)
CELLRAY_INSTANTIATE_ENTRY(RenderTileEntry)
CELLRAY_INSTANTIATE_ENTRY(RayVolumeEntry)
}  // namespace cellray
