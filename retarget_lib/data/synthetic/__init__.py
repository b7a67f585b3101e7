"""The embedded synthetic dataset: named skinned characters (:mod:`.characters`), motion families
authored from keyframes and IK (:mod:`.motions` with the tools of :mod:`.authoring`), built once
into the cache and loaded from there (:mod:`.dataset`)."""
