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
/// The patch stage's options from the `patches` section: the hand's layout split k × k, the
/// 98 k² nearest `patches.count` (98 for the thesis's 96, docs/patches.md), and the fit's
/// `c1_weight` and `fairness`.
PatchOptions patch_options(const PipelineOptions& o);
/// The skin's binding options from `rigging.smooth` (bone heat, or the thesis's rigid binding):
/// the skin's in `run`, and the patches' control points' weights come from it.
BindingOptions binding_options(const PipelineOptions& o);

}  // namespace handskin
