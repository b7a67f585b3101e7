"""Data, above the geometry layer: the manifest (``data_manifest.yaml``: every data source and
shipped checkpoint), the sources (:mod:`.sources`: CMU clips from Debian's ``assimp-testmodels``,
the mannequin-x skinned body, a reviewer's own ``mixamo-local`` folder), the embedded synthetic
dataset (:mod:`.synthetic`: characters and motions), the TDCN test split (:mod:`.splits`), and
``retarget data build|list|verify`` (:mod:`.build`, :mod:`.status`)."""
