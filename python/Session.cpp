#include "Session.h"

namespace kestrel::python {

std::shared_ptr<Session> session() {
    static std::shared_ptr<Session> s = [] {
        auto created = std::make_shared<Session>();
        created->loader.loadDirectories(defaultPluginDirectories(), created->registry);
        return created;
    }();
    return s;
}

}  // namespace kestrel::python
