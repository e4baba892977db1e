"""The physics and statistics of a descent: air density, the particle model along the profile
(Kaps, Nachbauer & Mössner 1996), the fit of μ, CdA and v0 to crossing times, the traverse
model, and the joint fit that compares a day's skis. Pure: no I/O, no threads."""
