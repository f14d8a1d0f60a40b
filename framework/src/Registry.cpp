#include "kestrel/Registry.h"

#include "ParamCheck.h"

namespace kestrel {

void Registry::add(PassDesc desc, PassFactory factory, std::string module) {
    if (desc.type.empty()) throw Error("a pass type with an empty name cannot be registered");
    if (auto it = types_.find(desc.type); it != types_.end()) {
        std::string first = it->second.module.empty() ? "built-in code" : it->second.module;
        std::string second = module.empty() ? "built-in code" : module;
        throw Error("duplicate pass type '" + desc.type + "': registered by " + first +
                    " and again by " + second);
    }
    std::string name = desc.type;
    types_.emplace(std::move(name), PassType{std::move(desc), std::move(factory), std::move(module)});
}

const PassType* Registry::find(std::string_view type) const {
    auto it = types_.find(type);
    return it == types_.end() ? nullptr : &it->second;
}

std::string Registry::nearest(std::string_view type) const {
    std::vector<std::string> names;
    for (const auto& [n, t] : types_) names.push_back(n);
    return detail::nearestName(type, names);
}

std::vector<const PassType*> Registry::all() const {
    std::vector<const PassType*> r;
    for (const auto& [n, t] : types_) r.push_back(&t);
    return r;
}

}  // namespace kestrel
