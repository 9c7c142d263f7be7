"""Pure guidance core: numpy in, numpy out. No sockets, no asyncio, no pymavlink, no clocks."""
