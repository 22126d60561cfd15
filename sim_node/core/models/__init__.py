"""
Reading what users bring: model files and text (MJCF, URDF), their meshes and assets.

:mod:`.sources` (what can be spawned), :mod:`.assets` (untrusted model text: safe XML,
includes, every file resolved, checked and copied once), :mod:`.resources` (which URIs and
folders may be read), :mod:`.description` (a URDF of a compiled model, for robot_description).
"""
