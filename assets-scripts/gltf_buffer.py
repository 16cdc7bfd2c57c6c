"""One glTF binary buffer with its buffer views and accessors, as the scene scripts write them
(make_material_preview.py, make_feature_scene.py, make_scale_scene.py).

    from gltf_buffer import BufferWriter
    buffer = BufferWriter()
    primitive = buffer.primitive({"POSITION": p, "NORMAL": n, "TEXCOORD_0": uv}, triangles, 0)
    gltf.update(buffer.gltf_fields("scene.bin"))  # buffers, bufferViews, accessors

Views are 4-byte aligned and tagged with their target; POSITION accessors carry min/max (glTF
requires them); indices are unsigned shorts when every vertex index fits, else unsigned ints.
Needs numpy.
"""

import numpy as np

FLOAT, UNSIGNED_SHORT, UNSIGNED_INT = 5126, 5123, 5125
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963

# Accessor type of each vertex attribute (texture coordinates are VEC2).
ATTRIBUTE_TYPES = {"POSITION": "VEC3", "NORMAL": "VEC3", "TANGENT": "VEC4"}


class BufferWriter:
    """One binary buffer with its buffer views and accessors, 4-byte aligned."""

    def __init__(self):
        self.data = bytearray()
        self.views = []
        self.accessors = []

    def add(self, array, component_type, accessor_type, target, bounds=False):
        """Appends `array` (rows = elements) as a view and an accessor; returns the accessor."""
        while len(self.data) % 4:
            self.data.append(0)
        raw = np.ascontiguousarray(array).tobytes()
        self.views.append(
            {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(raw), "target": target}
        )
        self.data.extend(raw)
        accessor = {
            "bufferView": len(self.views) - 1,
            "componentType": component_type,
            "count": int(array.shape[0]),
            "type": accessor_type,
        }
        if bounds:
            accessor["min"] = [float(x) for x in array.min(axis=0)]
            accessor["max"] = [float(x) for x in array.max(axis=0)]
        self.accessors.append(accessor)
        return len(self.accessors) - 1

    def indices(self, triangles, vertex_count):
        """The triangles' vertex indices as one SCALAR accessor (u16 when they fit)."""
        flat = triangles.reshape(-1)
        if vertex_count <= 0xFFFF:
            return self.add(flat.astype("<u2"), UNSIGNED_SHORT, "SCALAR", ELEMENT_ARRAY_BUFFER)
        return self.add(flat.astype("<u4"), UNSIGNED_INT, "SCALAR", ELEMENT_ARRAY_BUFFER)

    def primitive(self, attributes, triangles, material):
        """A TRIANGLES primitive: the indices first, then each attribute (float32) in the
        order of `attributes`, a dict from glTF attribute name to array."""
        indices = self.indices(triangles, attributes["POSITION"].shape[0])
        accessors = {
            name: self.add(
                array.astype("<f4"),
                FLOAT,
                ATTRIBUTE_TYPES.get(name, "VEC2"),
                ARRAY_BUFFER,
                name == "POSITION",
            )
            for name, array in attributes.items()
        }
        return {"attributes": accessors, "indices": indices, "material": material, "mode": 4}

    def gltf_fields(self, uri):
        """The document's `buffers` (this one, stored at `uri`), `bufferViews` and
        `accessors`."""
        return {
            "buffers": [{"uri": uri, "byteLength": len(self.data)}],
            "bufferViews": self.views,
            "accessors": self.accessors,
        }
