"""The application layer: command-line reports and runners that sit on top of the core (ecam)
and the rig (hil_sim). Nothing in ecam's core or in hil_sim imports this package."""
