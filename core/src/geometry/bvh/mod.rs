//! An eight-wide BVH with exact, uncompressed child boxes: obvhs builds a binary BVH, which is
//! collapsed into 8-wide nodes ([`build`]); the node test ([`node_test`]) and the traversal
//! ([`traverse`]) are ours.
//!
//! Why not obvhs's own traversal: its node test reads child boxes quantised to 8 bits (rounded
//! outward to a coarse grid, so rays enter children they miss), converts them to floats per
//! test, skips every box a ray leaves before an absolute t = 1e-4, and is built for SSE2 only.
//! Here each node holds its eight children's boxes as `f32` in structure-of-arrays form, so one
//! node test is a few 8-lane operations.

mod build;
pub(super) mod node_test;
mod traverse;

/// Marks a leaf in [`WideNode::child`]; the other bits are its first primitive.
const LEAF: u32 = 1 << 31;
/// An empty child slot in [`WideNode::child`] (its box is empty too, so no ray enters it).
const EMPTY: u32 = u32::MAX;
/// Most primitives in one leaf: a child with more becomes a node of its own.
const MAX_LEAF_PRIMITIVES: u32 = 3;

/// Trees must be shallower than this: the traversal's stack ([`traverse`]) is sized for it (as
/// obvhs's, `cwbvh::TRAVERSAL_STACK_SIZE`).
const TRAVERSAL_STACK_SIZE: usize = 32;

/// Most rays in a `PacketBoxTest`: two 8-lane registers hold one value of each. 16 rather
/// than 8: the packet's node test is paid once for twice as many rays of one pixel (the
/// dragon, 8 against 16: × 1.058 and × 1.053 in two runs, 1.011 n.s. in a third;
/// docs/performance.md).
pub const PACKET_SIZE: usize = 16;

/// Eight children's boxes and references (256 bytes, four cache lines).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
struct WideNode {
    /// min x, max x, min y, max y, min z, max z of each child; an empty slot has min = +∞ and
    /// max = −∞.
    bounds: [[f32; 8]; 6],
    /// Inner child: its node index; leaf: [`LEAF`] | its first primitive; empty: [`EMPTY`].
    child: [u32; 8],
    /// Primitives of each leaf child (1 to 3).
    count: [u8; 8],
}

impl WideNode {
    const EMPTY: WideNode = WideNode {
        bounds: [
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
        ],
        child: [EMPTY; 8],
        count: [0; 8],
    };
}

/// The BVH: node 0 is the root. Leaves index primitives in the tree's leaf order (returned by
/// [`WideBvh::build`]), which is the order the caller keeps its primitives in.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WideBvh {
    nodes: Vec<WideNode>,
}

impl WideBvh {
    /// Levels of nodes on the longest path from the root to a leaf (0 for an empty tree).
    #[cfg(test)]
    fn depth(&self) -> usize {
        if self.nodes.is_empty() {
            return 0;
        }
        let mut deepest = 0;
        let mut stack = vec![(0u32, 1usize)];
        while let Some((node, level)) = stack.pop() {
            deepest = deepest.max(level);
            for &child in &self.nodes[node as usize].child {
                if child != EMPTY && child & LEAF == 0 {
                    stack.push((child, level + 1));
                }
            }
        }
        deepest
    }
}
