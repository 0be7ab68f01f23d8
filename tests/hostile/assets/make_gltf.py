#!/usr/bin/env python3
"""Writes the glTF assets of the hostile-input corpus (run from this folder; the outputs are
committed). Each is a small .gltf with its buffer embedded as a data: URI, unless the case is
about buffer URIs."""

import base64
import json
import struct


def gltf(positions, indices=None, node=None, uri=None, pos_min=None, pos_max=None):
    """A one-mesh glTF: `positions` (x, y, z) triples, optional u16 `indices`, node fields."""
    pos = b"".join(struct.pack("<3f", *p) for p in positions)
    idx = b"" if indices is None else b"".join(struct.pack("<H", i) for i in indices)
    pad = b"\0" * ((4 - len(idx) % 4) % 4)
    data = pos + idx + pad
    finite = [p for p in positions if all(abs(c) < 3.4e38 for c in p)] or [(0, 0, 0)]
    lo = pos_min or [min(p[i] for p in finite) for i in range(3)]
    hi = pos_max or [max(p[i] for p in finite) for i in range(3)]
    accessors = [{"bufferView": 0, "componentType": 5126, "count": len(positions),
                  "type": "VEC3", "min": lo, "max": hi}]
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": len(pos)}]
    primitive = {"attributes": {"POSITION": 0}}
    if indices is not None:
        views.append({"buffer": 0, "byteOffset": len(pos), "byteLength": len(idx)})
        accessors.append({"bufferView": 1, "componentType": 5123, "count": len(indices),
                          "type": "SCALAR"})
        primitive["indices"] = 1
    node = dict(node or {})
    node["mesh"] = 0
    return {
        "asset": {"version": "2.0"},
        "buffers": [{"uri": uri or "data:application/octet-stream;base64,"
                     + base64.b64encode(data).decode(), "byteLength": len(data)}],
        "bufferViews": views,
        "accessors": accessors,
        "meshes": [{"primitives": [primitive]}],
        "nodes": [node],
        "scenes": [{"nodes": [0]}],
        "scene": 0,
    }


QUAD = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
QUAD_INDICES = [0, 1, 2, 0, 2, 3]


def write(name, doc, raw=None):
    with open(name, "w") as f:
        f.write(raw if raw is not None else json.dumps(doc, indent=1))
        f.write("\n")


write("quad.gltf", gltf(QUAD, QUAD_INDICES))
write("node_scale_1e30.gltf", gltf(QUAD, QUAD_INDICES, node={"scale": [1e30, 1e30, 1e30]}))
write("node_scale_0.gltf", gltf(QUAD, QUAD_INDICES, node={"scale": [0, 0, 0]}))
write("node_projective.gltf", gltf(QUAD, QUAD_INDICES, node={"matrix": [
    1, 0, 0, 0.5, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}))
write("positions_3e38.gltf", gltf([(-3e38, -3e38, 0), (3e38, -3e38, 0), (3e38, 3e38, 0)]))
write("truncated_indices.gltf", gltf(QUAD, [0, 1, 2, 0]))
write("truncated_vertices.gltf", gltf(QUAD))
write("absolute_uri.gltf", gltf(QUAD, QUAD_INDICES, uri="/etc/passwd"))
write("climbing_uri.gltf", gltf(QUAD, QUAD_INDICES, uri="../../../../etc/passwd"))
write("encoded_climbing_uri.gltf", gltf(QUAD, QUAD_INDICES, uri="%2e%2e/%2e%2e/etc/passwd"))
write("file_uri.gltf", gltf(QUAD, QUAD_INDICES, uri="file:///etc/passwd"))
# Infinite bounds as JavaScript's JSON.stringify writes them: null.
text = json.dumps(gltf(QUAD, QUAD_INDICES, pos_min=[-1, -1, 0], pos_max=[1, 1, 0]), indent=1)
write("infinite_bounds.gltf", None, text.replace('"max": [\n    1,\n    1,\n    0\n   ]',
                                                  '"max": [null, null, null]')
      .replace('"min": [\n    -1,\n    -1,\n    0\n   ]', '"min": [null, null, null]'))
write("positions_inf.gltf", gltf([(0, 0, 0), (float("inf"), 0, 0), (0, 1, 0)], [0, 1, 2],
                                 pos_min=[0, 0, 0], pos_max=[1, 1, 0]))


def with_camera_and_light(doc, camera_translation, yfov, intensity):
    """`doc` plus a camera node `eye` (looking down −z) and a KHR_lights_punctual point light."""
    doc["extensionsUsed"] = ["KHR_lights_punctual"]
    doc["extensions"] = {"KHR_lights_punctual": {"lights": [
        {"type": "point", "color": [1, 1, 1], "intensity": intensity}]}}
    doc["cameras"] = [{"type": "perspective",
                       "perspective": {"yfov": yfov, "znear": 0.01, "aspectRatio": 1.0}}]
    doc["nodes"] += [{"name": "eye", "camera": 0, "translation": camera_translation},
                     {"name": "lamp", "translation": [0, 0, 2],
                      "extensions": {"KHR_lights_punctual": {"light": 0}}}]
    doc["scenes"] = [{"nodes": [0, 1, 2]}]
    return doc


write("camera_light_ok.gltf", with_camera_and_light(gltf(QUAD, QUAD_INDICES), [0, 0, 5], 0.7, 10))
write("camera_far.gltf", with_camera_and_light(gltf(QUAD, QUAD_INDICES), [0, 0, 1e30], 0.7, 10))
write("camera_yfov_4.gltf", with_camera_and_light(gltf(QUAD, QUAD_INDICES), [0, 0, 5], 4.0, 10))
write("light_intensity_1e30.gltf",
      with_camera_and_light(gltf(QUAD, QUAD_INDICES), [0, 0, 5], 0.7, 1e30))
