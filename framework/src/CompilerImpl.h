#pragma once
// Internal state of a compiled graph, shared by the compiler and the executor.
#include <memory>
#include <string>
#include <vector>

#include "kestrel/Compiler.h"

namespace kestrel {

struct NodeState {
    std::string name;
    const PassType* type = nullptr;
    std::unique_ptr<Pass> pass;
    ParamValues params;
    int jsonIndex = 0;
    std::vector<int> inEdge;      ///< per port: edge index feeding it (inputs), else -1
    std::vector<bool> outAbsent;  ///< per port (outputs): will not be produced
    std::vector<std::string> absentReason;
    std::vector<std::string>
        rootCause;             ///< per absent output: "pass.port is absent (why)" at the origin
    std::vector<int> forward;  ///< per port (outputs): input port it forwards, else -1
    std::vector<int> portResource;  ///< per port: resource read (inputs) or written (outputs)
    std::vector<bool> portHistory;  ///< per input port: reads the previous frame's buffer
    bool absent = false;            ///< a required input is absent: nothing to compute
    std::string absentWhy;
    bool live = false;      ///< some needed output comes from this node
    bool executed = false;  ///< live and not fully forwarded
    std::vector<std::string> notes;
};

struct CompiledGraph::Impl {
    GraphDesc desc;
    std::vector<NodeState> nodes;  ///< in JSON order
    std::vector<int> topo;         ///< all nodes, same-frame topological order
    std::vector<int> order;        ///< executed nodes in execution order
    /// Per execution index: its step. Fused passes (Pass::executeFused) are adjacent in
    /// `order` and share a step; the memory plan's indices are steps.
    std::vector<int> stepOf;
    int steps = 0;
    std::vector<ResourceInfo> resources;
    int transientPlanes = 0;
    int unaliasedPlanes = 0;
    /// Per step: the transient planes no resource occupies while its passes run
    /// (PassIO::idlePlanes; CompiledGraph::idlePlanes maps an execution index to its step).
    std::vector<std::vector<int>> idlePlanes;
    CompileReport report;
    std::vector<std::pair<int, int>> marked;  ///< (node, port) of marked outputs
    std::vector<std::string> markedNames;     ///< "pass.port" of each marked output
    std::vector<int> markedResource;
};

}  // namespace kestrel
