// Grouping of a frame's objects into the two-level strategies' objects (see object_groups.hpp).
#include "object_groups.hpp"

#include <array>
#include <bit>
#include <map>
#include <tuple>

namespace dynbvh::study {

namespace {
bool is_identity(const io::Transform& t) { return t.m == io::Transform{}.m; }

/// A transform's bits (a map key with a strict order, whatever the floats hold).
std::array<std::uint32_t, 16> bits_of(const io::Transform& t) { return std::bit_cast<std::array<std::uint32_t, 16>>(t.m); }

bool tiles(std::span<const io::ObjectInstance> objects, std::size_t triangle_count) {
    std::size_t at = 0;
    for (const auto& o : objects) {
        if (o.first_triangle != at) return false;
        at += o.triangle_count;
    }
    return !objects.empty() && at == triangle_count;
}
} // namespace

Affine<float> affine_of(const io::Transform& t) {
    Affine<float> a;
    for (std::size_t r = 0; r < 3; ++r)
        for (std::size_t c = 0; c < 4; ++c) a.m[4 * r + c] = t.m[c * 4 + r];
    return a;
}

GroupedObjects::GroupedObjects(std::span<const io::ObjectInstance> objects, std::size_t triangle_count) {
    tiled_ = tiles(objects, triangle_count);
    if (!tiled_) {   // the whole frame as one deforming object
        if (triangle_count > 0) groups_.push_back({{}, std::uint32_t(triangle_count), true, false});
        return;
    }
    runs_.reserve(objects.size());
    for (const auto& o : objects) runs_.push_back({o.first_triangle, o.triangle_count});
    // Step: each object's group key; objects of one key form one group, in order of first member.
    ObjectGroup fixed{{}, 0, false, true};
    std::map<std::tuple<std::uint32_t, std::array<std::uint32_t, 16>>, std::size_t> bodies;   // (rigid body, transform) -> group
    for (std::uint32_t i = 0; i < objects.size(); ++i) {
        const io::ObjectInstance& o = objects[i];
        if (o.triangle_count == 0) continue;
        if (!o.animated) {
            fixed.members.push_back(i);
            fixed.triangles += o.triangle_count;
            continue;
        }
        const bool deforming = is_identity(o.transform);
        if (!deforming && o.rigid_body != io::no_rigid_body) {
            const auto [it, fresh] = bodies.try_emplace({o.rigid_body, bits_of(o.transform)}, groups_.size());
            if (!fresh) {
                groups_[it->second].members.push_back(i);
                groups_[it->second].triangles += o.triangle_count;
                continue;
            }
        }
        groups_.push_back({{i}, o.triangle_count, deforming, false});
    }
    if (!fixed.members.empty()) groups_.insert(groups_.begin(), std::move(fixed));
}

bool GroupedObjects::holds(std::span<const io::ObjectInstance> objects, std::size_t triangle_count) const {
    if (!tiled_) return !tiles(objects, triangle_count) && !groups_.empty() && groups_[0].triangles == triangle_count;
    if (objects.size() != runs_.size()) return false;
    for (std::size_t i = 0; i < objects.size(); ++i)
        if (objects[i].first_triangle != runs_[i].first || objects[i].triangle_count != runs_[i].second) return false;
    for (const ObjectGroup& g : groups_) {
        if (g.deforming || g.fixed) continue;
        for (std::size_t k = 1; k < g.members.size(); ++k)
            if (bits_of(objects[g.members[k]].transform) != bits_of(objects[g.members[0]].transform)) return false;
    }
    return true;
}

Affine<float> GroupedObjects::transform(std::size_t g, std::span<const io::ObjectInstance> objects) const {
    const ObjectGroup& grp = groups_[g];
    if (grp.deforming || grp.fixed) return {};
    return affine_of(objects[grp.members.front()].transform);
}

void GroupedObjects::object_space(std::size_t g, std::span<const io::ObjectInstance> objects, std::span<const Trianglef> tris,
                                  std::vector<Trianglef>& local, std::vector<std::uint32_t>& frame_index) const {
    const ObjectGroup& grp = groups_[g];
    local.clear();
    frame_index.clear();
    frame_index.reserve(grp.triangles);
    if (grp.deforming) {   // the frame's own run: no copy
        const auto [first, count] = run(g);
        for (std::uint32_t t = first; t < first + count; ++t) frame_index.push_back(t);
        return;
    }
    local.reserve(grp.triangles);
    const io::ObjectInstance& lead = objects[grp.members.front()];
    const Affine<float> inv = grp.fixed ? Affine<float>{} : inverse(affine_of(lead.transform), "object " + lead.name + "'s transform");
    for (const std::uint32_t m : grp.members) {
        const io::ObjectInstance& o = objects[m];
        for (std::uint32_t t = o.first_triangle; t < o.first_triangle + o.triangle_count; ++t) {
            const Trianglef& w = tris[t];
            local.push_back(grp.fixed ? w : Trianglef{inv.point(w.p0), inv.point(w.p1), inv.point(w.p2)});
            frame_index.push_back(t);
        }
    }
}

} // namespace dynbvh::study
