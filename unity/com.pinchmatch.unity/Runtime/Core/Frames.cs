// pinchmatch's frames and Unity's.
//
// pinchmatch writes millimetres, right-handed, in each object's file frame (the file's coordinates
// scaled to mm; its up is the file's: +Z for STL, OBJ and PLY unless told otherwise, +Y for glTF).
// Its glTF files (the match scenes, level.glb) are metres, right-handed, +Y up: a file point x (mm)
// is C x there, C = Q / 1000 with Q the smallest rotation taking the file's up onto +Y.
// Unity is metres, left-handed, +Y up; glTFast and UnityGLTF import a glTF point (x, y, z) as
// (-x, y, z): the mirror S = diag(-1, 1, 1). A rotation R of glTF's frame is S R S in Unity's, the
// quaternion (x, y, z, w) becoming (x, -y, -z, w).
using System;

namespace Pinchmatch
{
    public static class Frames
    {
        /// <summary>S: glTF's frame to Unity's as the glTF importers map it (x mirrored).</summary>
        public static readonly Affine GltfToUnityMap =
            new Affine(Mat3.Rows(new Vec3(-1, 0, 0), new Vec3(0, 1, 0), new Vec3(0, 0, 1)), Vec3.Zero);

        public static Vec3 GltfToUnity(Vec3 p) { return new Vec3(-p.X, p.Y, p.Z); }

        public static Vec3 UnityToGltf(Vec3 p) { return new Vec3(-p.X, p.Y, p.Z); }

        public static Quat GltfToUnity(Quat q) { return new Quat(q.X, -q.Y, -q.Z, q.W); }

        public static Quat UnityToGltf(Quat q) { return new Quat(q.X, -q.Y, -q.Z, q.W); }

        public static Pose GltfToUnity(Pose p)
        {
            return new Pose(GltfToUnity(p.Position), GltfToUnity(p.Rotation));
        }

        /// <summary>A map of glTF's frame written in Unity's: S M S.</summary>
        public static Affine GltfToUnity(Affine m)
        {
            return GltfToUnityMap * m * GltfToUnityMap;
        }

        /// <summary>The smallest rotation taking the unit vector a onto b; opposite vectors get a
        /// half turn about an axis perpendicular to them (a x X, or a x Y where a is along X), as
        /// pinchmatch chooses it.</summary>
        public static Mat3 RotationBetween(Vec3 a, Vec3 b)
        {
            a = a.Normalized;
            b = b.Normalized;
            double c = Vec3.Dot(a, b);
            if (c < -1.0 + 1e-12)
            {
                var perp = Vec3.Cross(a, new Vec3(1, 0, 0));
                if (perp.Length < 1e-6) perp = Vec3.Cross(a, new Vec3(0, 1, 0));
                perp = perp.Normalized;
                return Mat3.Rows(new Vec3(2 * perp.X * perp.X - 1, 2 * perp.X * perp.Y, 2 * perp.X * perp.Z),
                                 new Vec3(2 * perp.Y * perp.X, 2 * perp.Y * perp.Y - 1, 2 * perp.Y * perp.Z),
                                 new Vec3(2 * perp.Z * perp.X, 2 * perp.Z * perp.Y, 2 * perp.Z * perp.Z - 1));
            }
            var v = Vec3.Cross(a, b);
            var K = Mat3.Rows(new Vec3(0, -v.Z, v.Y), new Vec3(v.Z, 0, -v.X), new Vec3(-v.Y, v.X, 0));
            var KK = K * K;
            double f = 1.0 / Math.Max(1.0 + c, 1e-300);
            return new Mat3
            {
                M00 = 1 + K.M00 + KK.M00 * f, M01 = K.M01 + KK.M01 * f, M02 = K.M02 + KK.M02 * f,
                M10 = K.M10 + KK.M10 * f, M11 = 1 + K.M11 + KK.M11 * f, M12 = K.M12 + KK.M12 * f,
                M20 = K.M20 + KK.M20 * f, M21 = K.M21 + KK.M21 * f, M22 = 1 + K.M22 + KK.M22 * f,
            };
        }

        /// <summary>C: a file's mm to glTF's metres for a file whose up is <paramref name="up"/>
        /// (the scenes' "pinchmatch:file_mm_to_gltf_m").</summary>
        public static Affine FileMmToGltfM(Vec3 up)
        {
            var Q = RotationBetween(up, new Vec3(0, 1, 0));
            return new Affine(Q * Mat3.Scale(0.001), Vec3.Zero);
        }

        /// <summary>S C: a file's mm to Unity's metres, as a glTF importer shows pinchmatch's glTF of
        /// that file (a match scene's nodes: the prop's up; a level's prop node: +Y, its mesh kept in
        /// the prop's own frame).</summary>
        public static Affine FileMmToUnity(Vec3 up)
        {
            return GltfToUnityMap * FileMmToGltfM(up);
        }

        /// <summary>A unit direction of the file frame, in Unity's.</summary>
        public static Vec3 FileDirectionToUnity(Vec3 up, Vec3 direction)
        {
            return FileMmToUnity(up).Direction(direction).Normalized;
        }
    }
}
