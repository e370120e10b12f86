"""The virtual EtherCAT network: emulated slave controllers and CiA402 drives answering real frames on a veth pair."""
