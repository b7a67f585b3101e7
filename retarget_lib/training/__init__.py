"""Training, above the methods: the loop every model shares (:mod:`.loop`: seeded, logged,
checkpointed, resumable), TDCN and its Table 4 rows (:mod:`.tdcn`), and the contact-aware network
on its Table 3 energies (:mod:`.contact`)."""
