"""Retargeting methods, above the models and losses: one module per method (:mod:`.copy`,
:mod:`.copy_rest`, :mod:`.tdcn`, :mod:`.nkn`, :mod:`.contact` with :mod:`.eso`), the registry that
names them (:mod:`.registry`: where a method is added), and :func:`~.retarget.retarget_file`, which
retargets a file with any of them."""
