#pragma once
// Pass types by name. Every pass, built-in ones too, arrives through a plugin module that
// registers its types here; the registry records which module each type came from.
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "kestrel/Pass.h"

namespace kestrel {

using PassFactory = std::function<std::unique_ptr<Pass>(const ParamValues&)>;

struct PassType {
    PassDesc desc;
    PassFactory create;
    std::string module;  ///< path of the plugin that registered it ("" when registered in code)
};

class Registry {
public:
    /// Throws Error on a duplicate type name (naming both modules).
    void add(PassDesc desc, PassFactory factory, std::string module = {});

    template <class T>
    void add(std::string module = {}) {
        add(T::describe(), [](const ParamValues& p) { return std::make_unique<T>(p); },
            std::move(module));
    }

    const PassType* find(std::string_view type) const;
    /// The registered type name closest to `type` (edit distance), for "did you mean".
    std::string nearest(std::string_view type) const;
    std::vector<const PassType*> all() const;  ///< sorted by name

private:
    std::map<std::string, PassType, std::less<>> types_;
};

}  // namespace kestrel
