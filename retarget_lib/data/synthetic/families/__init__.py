"""The motion families of :mod:`retarget_lib.data.synthetic.motions`, one function per family
``(rig, rng, t) -> Plan`` authored with :mod:`retarget_lib.data.synthetic.authoring`:
:mod:`.locomotion` (walk, run, turn, jump), :mod:`.gestures` (wave, clap, pray, hands on hips,
touch head), :mod:`.fighting` (punch, kick, squat), all starting from :mod:`.standing`."""
