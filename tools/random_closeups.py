#!/usr/bin/env python3
"""Writes close-up scenes of a binary STL at randomly chosen triangles.

usage: tools/random_closeups.py SCENE.json MESH.stl COUNT FACTOR PREFIX [SEED]

SCENE is a scene whose camera frames the mesh (`raylod scene MESH.stl`),
with the mesh in world coordinates (no transform). Each close-up keeps the
scene and moves the camera: it looks at the centroid of a triangle picked
uniformly at random (Python's random with SEED, default 7) from FACTOR
times the original distance, along the original viewing direction. Writes
PREFIX_0.json .. PREFIX_{COUNT-1}.json. The README's "Close-ups at random
triangles" used FACTOR 0.12 with seeds 7 and 11.
"""
import json
import os
import random
import struct
import sys


def main(argv):
    if len(argv) not in (6, 7):
        sys.stderr.write(__doc__)
        return 2
    scene_path, mesh_path, count, factor, prefix = argv[1], argv[2], int(argv[3]), float(argv[4]), argv[5]
    seed = int(argv[6]) if len(argv) == 7 else 7
    try:
        with open(scene_path) as f:
            scene = json.load(f)
        eye, look = scene['camera']['eye'], scene['camera']['look_at']
    except (OSError, ValueError, KeyError, TypeError) as e:
        sys.stderr.write('%s: not a readable scene with a camera (%s)\n' % (scene_path, e))
        return 1
    try:
        with open(mesh_path, 'rb') as f:
            data = f.read()
    except OSError as e:
        sys.stderr.write('%s: %s\n' % (mesh_path, e.strerror))
        return 1
    if len(data) < 84:
        sys.stderr.write('%s: not a binary STL (%d bytes)\n' % (mesh_path, len(data)))
        return 1
    triangles = struct.unpack('<I', data[80:84])[0]
    if triangles == 0 or len(data) < 84 + 50 * triangles:
        sys.stderr.write('%s: not a binary STL with %d triangles\n' % (mesh_path, triangles))
        return 1
    rng = random.Random(seed)
    for k in range(count):
        i = rng.randrange(triangles)
        v = struct.unpack('<12f', data[84 + 50 * i:84 + 50 * i + 48])
        centroid = [(v[3 + j] + v[6 + j] + v[9 + j]) / 3 for j in range(3)]
        scene['camera']['look_at'] = centroid
        scene['camera']['eye'] = [centroid[j] + (eye[j] - look[j]) * factor for j in range(3)]
        out = '%s_%d.json' % (prefix, k)
        try:
            with open(out + '.tmp', 'w') as f:  # written whole, then renamed
                json.dump(scene, f, indent=1)
            os.replace(out + '.tmp', out)
        except OSError as e:
            sys.stderr.write('%s: %s\n' % (out, e.strerror))
            return 1
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv))
