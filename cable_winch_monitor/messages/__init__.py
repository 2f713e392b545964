"""The monitor's messages: the fields of every topic it reads and writes, its records, /tf frames and 3-D scene."""
