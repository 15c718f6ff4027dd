"""The sewing analyses built on the engine: what the mechanisms do for stitch formation.

``timing`` (needle, shuttle and take-up events, the hook drive's timing), ``feed`` (the feed
dog: stitch length, lift, scale marks, feed timing), ``checks`` (every timing and feed check of
a lockstitch machine against the published facts), ``thread`` (the needle thread's supply and
demand), ``transmission`` (pressure angles, regulator torque, needle force) and ``embroidery``
(Kozlov's double-crank take-up). They read a machine through its ``[sewing]`` and ``[thread]``
roles, so they work for any machine file that names them.
"""
