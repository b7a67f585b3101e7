"""Data sources fetched or found outside the library: CMU clips (:mod:`.cmu`), the mannequin-x body
(:mod:`.mannequin`), a reviewer's Mixamo folder (:mod:`.mixamo_local`)."""
