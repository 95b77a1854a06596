"""The host scene uploaded to the device: ``DeviceScene`` and the scene's ``Features`` (``device_scene``),
the list-of-placements front end for instanced meshes (``instances``), and per-corner tangents for
normal maps and anisotropy (``tangents``, numpy). It sits above every family: it asks their
registries what a scene needs and fills their structs."""
