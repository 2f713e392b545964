"""When the monitor's stages run live: merged in the callbacks, solved by a worker thread."""
