"""What comes from outside, measured before it is believed: bounded JSON and YAML, zips, the
request body's size, NUL characters and bodies no form parse can read."""
