"""Evaluation, the layer above training: TDCN's Table 4 (:mod:`.tdcn`), the contact-aware tables
1, 3, 5 and 6 (:mod:`.contact`), every number the papers report (:mod:`.paper`), and the speed
benchmarks of ``retarget bench`` (:mod:`.bench`, :mod:`.bench_contact`, :mod:`.timing`)."""
