#pragma once
/// The stages' option structs made from the pipeline's parameters (which are checked when the
/// pipeline is read: PipelineOptions::IsValid).
#include "pipeline/options.hpp"
#include "patches/patches.hpp"
#include "register/registration.hpp"
#include "skin/skin_mesh.hpp"

namespace handskin {

/// The registration stage's options from the pipeline's `markers` and `registration` sections.
RegistrationOptions registration_options(const PipelineOptions& o);
/// The skin stage's options from the pipeline's `slicing` and `skin` sections.
SkinOptions skin_options(const PipelineOptions& o);
/// The patch stage's options from `patches.count`: the layout nearest to that many patches
/// (palm 8 × 4 and 4 × 3 per digit make 92 for the thesis's 96, docs/patches.md).
PatchOptions patch_options(const PipelineOptions& o);

}  // namespace handskin
