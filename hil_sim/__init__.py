"""hil_sim: the software-in-the-loop rig -- a virtual CANopen CiA 402 servo with motor, gear,
coupling and load, driven by a master-axis loop over python-can's virtual bus."""
