#include "Arrays.h"

#include <kestrel/Error.h>

#include <string>

namespace py = pybind11;

namespace kestrel::python {
namespace {

template <class T>
py::array interleave(const ImageView& view, const T* const* planes) {
    const int h = view.height(), w = view.width(), c = view.channels();
    py::array_t<T> out({py::ssize_t(h), py::ssize_t(w), py::ssize_t(c)});
    T* dst = out.mutable_data();
    const size_t n = view.pixels();
    for (size_t i = 0; i < n; ++i)
        for (int ch = 0; ch < c; ++ch) dst[i * size_t(c) + size_t(ch)] = planes[ch][i];
    return out;
}

}  // namespace

py::array copyToArray(const ImageView& view) {
    if (!view.valid()) throw Error("the resource holds no image (not computed this frame)");
    if (view.format == Format::Int32) {
        const int32_t* plane = view.ints();
        return interleave<int32_t>(view, &plane);
    }
    const float* planes[4] = {view.planes[0], view.planes[1], view.planes[2], view.planes[3]};
    return interleave<float>(view, planes);
}

Image imageFromArray(const py::array& array, const char* what) {
    auto a = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(array);
    if (!a || (a.ndim() != 2 && a.ndim() != 3))
        throw Error(std::string(what) + ": expected a float array of shape (height, width) or " +
                    "(height, width, channels)");
    const int h = int(a.shape(0)), w = int(a.shape(1));
    const int c = a.ndim() == 3 ? int(a.shape(2)) : 1;
    if (c < 1 || c > 4 || h < 1 || w < 1)
        throw Error(std::string(what) + ": expected 1 to 4 channels and a non-empty image, got " +
                    std::to_string(h) + "x" + std::to_string(w) + "x" + std::to_string(c));
    Image img(w, h, Format(int(Format::Float) + c - 1));
    const float* src = a.data();
    for (size_t i = 0; i < img.view().pixels(); ++i)
        for (int ch = 0; ch < c; ++ch) img.channel(ch)[i] = src[i * size_t(c) + size_t(ch)];
    return img;
}

}  // namespace kestrel::python
