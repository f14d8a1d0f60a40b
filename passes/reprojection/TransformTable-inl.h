// Per-object transforms of the matrix path (GAMES202 homework 5). Included once per SIMD target
// by Reproject.cpp (hwy/foreach_target.h): the toggled guard below.
#if defined(KESTREL_REPROJECTION_TRANSFORM_TABLE_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef KESTREL_REPROJECTION_TRANSFORM_TABLE_INL_H_
#undef KESTREL_REPROJECTION_TRANSFORM_TABLE_INL_H_
#else
#define KESTREL_REPROJECTION_TRANSFORM_TABLE_INL_H_
#endif

#include <hwy/highway.h>
#include <kestrel/Kestrel.h>

#include <cstdint>
#include <map>
#include <vector>

HWY_BEFORE_NAMESPACE();
namespace kestrel::HWY_NAMESPACE {
namespace {

/// Per-object transforms of the matrix path: current world -> previous pixel (and previous
/// camera, for the expected previous depth). GAMES202: Screen_{i-1} = P V M_{i-1} M_i^-1 World_i.
struct ObjectTransforms {
    Mat4 toPrevPixel, toPrevCamera;
};

class TransformTable {
public:
    TransformTable(const SceneData& cur, const SceneData& prev) {
        fallback_ = {prev.worldToPixel, prev.worldToCamera};
        for (const auto& [id, o2w] : cur.objectToWorld) {
            auto it = prev.objectToWorld.find(id);
            auto inv = inverse(o2w);
            if (it == prev.objectToWorld.end() || !inv) continue;
            Mat4 motion = it->second * *inv;
            byId_[id] = {prev.worldToPixel * motion, prev.worldToCamera * motion};
        }
        if (!byId_.empty()) {
            lo_ = byId_.begin()->first;
            int64_t span = int64_t(byId_.rbegin()->first) - lo_ + 1;
            if (span <= 65536) {  // dense table: no map lookup per pixel
                dense_.assign(size_t(span), fallback_);
                for (const auto& [id, t] : byId_) dense_[size_t(id - lo_)] = t;
            }
        }
    }
    const ObjectTransforms& fallback() const { return fallback_; }
    const ObjectTransforms& get(int32_t id) const {
        if (!dense_.empty()) {
            int64_t i = int64_t(id) - lo_;
            return i >= 0 && i < int64_t(dense_.size()) ? dense_[size_t(i)] : fallback_;
        }
        auto it = byId_.find(id);
        return it == byId_.end() ? fallback_ : it->second;
    }

private:
    ObjectTransforms fallback_;  // static objects: camera motion only
    std::map<int32_t, ObjectTransforms> byId_;
    std::vector<ObjectTransforms> dense_;
    int32_t lo_ = 0;
};

}  // namespace
}  // namespace kestrel::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // toggled include guard
