"""EtherCAT on the core's SOEM master: bringing a segment up, the real arm's bus, host checks, scanning, the
virtual network."""
