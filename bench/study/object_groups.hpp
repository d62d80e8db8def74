// The two-level strategies' objects, ours and Embree's alike: the frame's objects grouped into the
// bodies that move together, so that a rigid body is one object tree and one instance however many
// of the frame's objects (one per material or part, as BART files give them) it is made of.
#pragma once

#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include <dynbvh/affine.hpp>
#include <dynbvh/io/scene.hpp>
#include <dynbvh/triangle.hpp>

namespace dynbvh::study {

/// One object of a two-level scene: one or more of the frame's objects.
struct ObjectGroup {
    std::vector<std::uint32_t> members;   ///< indices into the frame's objects, in frame order
    std::uint32_t triangles = 0;          ///< the members' triangles together
    /// Given anew every frame (refitted or rebuilt): a single animated object whose transform is the
    /// identity (a cloth: the built-in scenes give world-space triangles only), or the whole frame.
    bool deforming = false;
    /// The frame's non-animated objects together: they never move, so their world-space triangles
    /// are the object's, under the identity.
    bool fixed = false;
};

/// The frame's objects as groups, and the layout they were made for.
class GroupedObjects {
public:
    /// Groups `objects` of a frame of `triangle_count` triangles: the non-animated objects into one
    /// fixed group; animated objects with a transform and the same io::ObjectInstance::rigid_body
    /// and the same transform into one group each; every other animated object alone (deforming when its
    /// transform is the identity). A frame whose objects do not tile its triangles in order is one
    /// deforming group. Groups without triangles are dropped. O(objects log objects).
    GroupedObjects(std::span<const io::ObjectInstance> objects, std::size_t triangle_count);

    const std::vector<ObjectGroup>& groups() const noexcept { return groups_; }

    /// Whether a later frame's `objects` fit these groups: the same runs of triangles, and every
    /// rigid group's members still sharing one transform. O(objects).
    bool holds(std::span<const io::ObjectInstance> objects, std::size_t triangle_count) const;

    /// Group g's placement this frame: its first member's transform, or the identity for deforming and
    /// fixed groups.
    Affine<float> transform(std::size_t g, std::span<const io::ObjectInstance> objects) const;

    /// Group g's triangles in object space (world-space triangles through the inverse of its placement
    /// this frame; fixed groups as they are) into `local`, and the frame's index of each into `frame_index`.
    /// A deforming group's triangles are the frame's own run (see run()): `local` stays empty for it.
    /// Throws std::invalid_argument naming the object when its transform is not invertible.
    void object_space(std::size_t g, std::span<const io::ObjectInstance> objects, std::span<const Trianglef> tris,
                      std::vector<Trianglef>& local, std::vector<std::uint32_t>& frame_index) const;

    /// Group g's run of the frame's triangles when it is deforming: its one object's, or the whole frame
    /// (the group without members of a frame whose objects do not tile it).
    std::pair<std::uint32_t, std::uint32_t> run(std::size_t g) const noexcept {
        const ObjectGroup& grp = groups_[g];
        return grp.members.empty() ? std::pair<std::uint32_t, std::uint32_t>{0, grp.triangles} : runs_[grp.members.front()];
    }

private:
    std::vector<ObjectGroup> groups_;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> runs_;   // (first, count) per frame object
    bool tiled_ = false;                                          // objects tile the frame
};

/// Affine of an io::Transform (column-major 4x4 to the library's row-major 3x4).
Affine<float> affine_of(const io::Transform& t);

} // namespace dynbvh::study
