#version 450
// Breadth-first quadtree traversal in one workgroup with ping-pong lists (FC5 section 4.2), from
// the top level's resident nodes (overview levels, format/SPEC.md section 19, or the roots): a
// node splits when its screen-space error asks for it and no child is waiting to stream in
// (children that do not exist leave their quarter to the parent).
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = TV_TRAVERSE_GROUP) in;

layout(std430, set = 0, binding = 4) buffer NodeList { uint node_list[]; };  // header + entries
layout(std430, set = 0, binding = 5) writeonly buffer PatchWork { uint patch_work[]; };
layout(std430, set = 0, binding = 7) buffer Draw { uint draw[]; };
// Two lists of `cap` (slot count) entries each: a level holds distinct resident slots.
layout(std430, set = 0, binding = 17) coherent buffer Lists { uint lists[]; };
layout(std430, set = 0, binding = 18) readonly buffer Tree { uint tree[]; };  // config.h "Tree buffer"

shared uint counts[2];
shared uint final_count;
shared uint item_count;
shared uint level_counts[TV_MAX_LEVELS];
shared uint overflow;

// Child c of the node in `slot`, from the tree buffer (TV_SLOT_EMPTY: exists, not resident;
// TV_SLOT_INVALID: no such node).
uint child_slot(uint slot, int c, uint cap) {
  uint w = tree[TV_TREE_START + cap + 2u * slot + uint(c >> 1)];
  return (w >> (16u * uint(c & 1))) & 0xFFFFu;
}

// Same operations, in the same order, as wants_split() in src/reference.cpp.
bool wants_split(NodeDesc n, float error_m) {
  uint level = node_level(n);
  float mnx = rel_x(half_metres(n.x, level, 0u));
  float mxx = rel_x(half_metres(n.x + 1u, level, 0u));
  float mny = rel_y(half_metres(n.y, level, 0u));
  float mxy = rel_y(half_metres(n.y + 1u, level, 0u));
  float mnz = rel_z(n.min_height);
  float mxz = rel_z(n.max_height);
  precise float dx = max(max(mnx, -mxx), 0.0);
  precise float dy = max(max(mny, -mxy), 0.0);
  precise float dz = max(max(mnz, -mxz), 0.0);
  precise float d2 = dx * dx + dy * dy + dz * dz;
  precise float e = error_m * frame.cam_frac.w;
  precise float t = frame.lod.x;
  precise float lhs = e * e;
  precise float rhs = (t * t) * d2;
  return lhs > rhs;
}

// Whether an edge-adjacent root wants to split (its finer nodes may then border this root).
bool neighbour_root_splits(NodeDesc d) {
  const ivec2 offsets[4] = ivec2[](ivec2(1, 0), ivec2(-1, 0), ivec2(0, 1), ivec2(0, -1));
  for (int k = 0; k < 4; ++k) {
    ivec2 p = ivec2(d.x, d.y) + offsets[k];
    if (p.x < 0 || p.y < 0 || p.x >= int(frame.world.x) || p.y >= int(frame.world.y)) continue;
    uint s = texelFetch(root_tex, p, 0).r;
    if (s < TV_SLOT_INVALID && root_in_window(uint(p.x), uint(p.y)) && wants_split(nodes[s], nodes[s].geometric_error))
      return true;
  }
  return false;
}

void emit_final(uint slot, uint mask, uint coarse, NodeDesc d) {
  uint level = node_level(d);
  uint k = atomicAdd(final_count, 1u);
  node_list[TV_NL_HEADER + k] = slot | (mask << TV_ENTRY_QUAD_SHIFT) | (coarse << TV_ENTRY_COARSE_SHIFT);
  atomicAdd(level_counts[level], 1u);
  // Patch work items: the patches of the drawn quadrants (all of a coarsened root's).
  uint pps = uint(TV_PATCHES_PER_SIDE) >> coarse, half_pps = pps >> 1;
  uint n = coarse > 0u ? pps * pps : bitCount(mask) * 16u;
  uint base = atomicAdd(item_count, n);
  for (uint py = 0u; py < pps; ++py)
    for (uint px = 0u; px < pps; ++px) {
      uint quadrant = (px >= half_pps ? 1u : 0u) | (py >= half_pps ? 2u : 0u);
      if (coarse == 0u && (mask & (1u << quadrant)) == 0u) continue;
      patch_work[base++] = k | (px << 16) | (py << 19);
    }
}

void main() {
  uint t = gl_LocalInvocationIndex;
  if (t == 0u) {
    counts[0] = 0u;
    counts[1] = 0u;
    final_count = 0u;
    item_count = 0u;
    overflow = 0u;
    for (int l = 0; l < TV_MAX_LEVELS; ++l) level_counts[l] = 0u;
  }
  barrier();
  // Start: the top level's resident nodes, listed by the CPU.
  uint cap = tree[1];
  uint starts = min(tree[0], cap);
  for (uint r = t; r < starts; r += TV_TRAVERSE_GROUP) lists[r] = tree[TV_TREE_START + r];
  if (t == 0u) counts[0] = starts;
  memoryBarrierBuffer();
  barrier();
  uint cur = 0u;
  for (int level = int(frame.misc.x); level >= 0; --level) {
    uint nxt = cur ^ 1u;
    uint n = min(counts[cur], cap);
    for (uint i = t; i < n; i += TV_TRAVERSE_GROUP) {
      uint slot = lists[cur * cap + i];
      if (slot == 0xFFFFFFFFu) continue;  // a reservation that did not fit
      NodeDesc d = nodes[slot];
      uint mask = 15u, coarse = 0u;
      // Below the roots only inside the LOD map window (config.h "LOD map").
      bool wants = level > 0 && wants_split(d, d.geometric_error) && (level != TV_ROOT_LEVEL || root_in_window(d.x, d.y));
      if (wants) {
        uint child[4];
        bool any_empty = false, any_resident = false;
        uint resident = 0u;
        for (int c = 0; c < 4; ++c) {
          child[c] = child_slot(slot, c, cap);
          any_empty = any_empty || child[c] == TV_SLOT_EMPTY;
          bool res = child[c] < TV_SLOT_INVALID;
          any_resident = any_resident || res;
          resident += res ? 1u : 0u;
        }
        if (!any_empty && any_resident) {
          uint k = atomicAdd(counts[nxt], resident);
          if (k + resident <= cap) {
            for (int c = 0; c < 4; ++c)
              if (child[c] < TV_SLOT_INVALID) {
                lists[nxt * cap + k++] = child[c];
                mask &= ~(1u << uint(c));
              }
          } else {
            for (uint q = k; q < min(k + resident, cap); ++q) lists[nxt * cap + q] = 0xFFFFFFFFu;
            atomicAdd(overflow, 1u);
          }
        }
      } else if (level == TV_ROOT_LEVEL) {
        // Coarsest drawing whose error the target still accepts (level 8 only beside roots that
        // do not split, see config.h).
        for (int c = TV_MAX_COARSEN; c >= 1; --c)
          if (!wants_split(d, coarse_error[slot][c]) && (c < 3 || !neighbour_root_splits(d))) {
            coarse = uint(c);
            break;
          }
      }
      if (mask != 0u) emit_final(slot, mask, coarse, d);
    }
    memoryBarrierBuffer();
    barrier();
    if (t == 0u) counts[cur] = 0u;
    barrier();
    cur = nxt;
  }
  memoryBarrierBuffer();
  barrier();
  if (t == 0u) {
    node_list[TV_NL_DISPATCH + 0] = final_count;
    node_list[TV_NL_DISPATCH + 1] = 1u;
    node_list[TV_NL_DISPATCH + 2] = 1u;
    node_list[TV_NL_COUNT] = final_count;
    for (int l = 0; l < TV_MAX_LEVELS; ++l) node_list[TV_NL_LEVEL_COUNTS + l] = level_counts[l];
    node_list[TV_NL_OVERFLOW] = overflow;
    node_list[TV_NL_PATCH_DISPATCH + 0] = (item_count + uint(TV_PATCH_GROUP) - 1u) / uint(TV_PATCH_GROUP);
    node_list[TV_NL_PATCH_DISPATCH + 1] = 1u;
    node_list[TV_NL_PATCH_DISPATCH + 2] = 1u;
    node_list[TV_NL_PATCH_ITEMS] = item_count;
    // Reset the draw commands (range r = group * TV_MESHES + e: mesh e of the index buffer,
    // instances from capacity * r) and the counters for the patch pass.
    for (int k = 0; k < TV_DRAW_UINTS; ++k) draw[k] = 0u;
    draw[TV_CNT_CONSIDERED] = item_count;
    for (uint r = 0u; r < uint(TV_PATCH_RANGES); ++r) {
      uint e = r % uint(TV_MESHES), first = 0u;
      for (uint k = 0u; k < e; ++k) first += (256u >> (2u * k)) * 6u;
      draw[r * 5u + 0u] = (256u >> (2u * e)) * 6u;  // indexCount: (16 >> e)^2 quads
      draw[r * 5u + 2u] = first;                      // firstIndex
      draw[r * 5u + 4u] = frame.misc.w * r;           // firstInstance
    }
  }
}
