"""SUMO traffic: floating-car data read and converted to box poses at a frame rate
(fcd), vehicle type sizes (vtypes), running SUMO (sumo_run)."""
