"""Data sources (``data_manifest.yaml``): synthetic characters and motions, CMU clips from Debian's
``assimp-testmodels``, the mannequin-x skinned body, and a reviewer's own ``mixamo-local`` folder."""
