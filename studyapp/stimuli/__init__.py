"""What participants watch and where it comes from: the systems compared (checkpoints,
natural motion, submitted motion, videos), the controls they are given, the clips made
from them (planned, sampled, rendered, sent to the workers), and the exports of controls
and motion for other labs."""
