#pragma once
// Engine images <-> numpy. Engine images are planar (one plane per channel); numpy arrays here
// are (height, width, channels), C-contiguous: float32, or int32 for Format::Int32.
#include <kestrel/Image.h>
#include <pybind11/numpy.h>

namespace kestrel::python {

/// A new array holding a copy of `view` (it owns its memory: valid after the engine's is gone).
pybind11::array copyToArray(const ImageView& view);

/// A planar float image copied from an (H, W, C) or (H, W) float array (any float dtype is
/// converted). Throws kestrel::Error naming `what` for another shape.
Image imageFromArray(const pybind11::array& array, const char* what);

}  // namespace kestrel::python
