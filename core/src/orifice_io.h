#pragma once
// The regurgitant orifice in HDF5 (group `orifice`), shared by the simulation and patient files.
#include <optional>

#include "hdf5_io.h"
#include "mvtwin/core/regurgitant_orifice.h"

namespace mvtwin::h5 {

/// Writes group `orifice` under `parent`: the measures, the openings, the column gaps and, when
/// given, the fine atrial and ventricular surfaces they were measured on.
void write_orifice(const Location& parent, const RegurgitantOrifice& orifice,
                   const LeafletGrid* la_surface, const LeafletGrid* lv_surface);
/// Reads such a group; *la and *lv get its surfaces when it has them. Throws mvtwin::Error naming
/// the dataset for a malformed group.
RegurgitantOrifice read_orifice(const Location& group, std::optional<LeafletGrid>* la,
                                std::optional<LeafletGrid>* lv);

}  // namespace mvtwin::h5
