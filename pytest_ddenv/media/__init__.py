"""What a reduction shows besides its files (layer 9, beside `pytest_ddenv.render`, the pictures).

`writer` (`--ddenv-media`: which media to make, and `write_media`), `animate` (GIFs of runs, drawn by
pybullet's TinyRenderer where it is installed, else by MuJoCo's renderer: `mujoco_scene`, in a helper process
with an OpenGL backend that starts: `gl_helper`; an arm's camera over its table: `table_camera`),
`recording` (a Rerun `.rrd` of runs; an arm's links: `arm_links`), `mcap` (the same as MCAP in Foxglove's
schemas), `content` (what both recordings show, as numbers), `palette` (the colours they share).
"""
