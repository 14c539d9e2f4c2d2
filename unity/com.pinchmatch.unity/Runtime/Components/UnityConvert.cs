// Between Unity's float types and the core's doubles (the same frame: Unity's world, metres).
using UnityEngine;

namespace Pinchmatch.Unity
{
    public static class UnityConvert
    {
        public static Vec3 ToCore(Vector3 v) { return new Vec3(v.x, v.y, v.z); }

        public static Quat ToCore(Quaternion q) { return new Quat(q.x, q.y, q.z, q.w); }

        public static Pinchmatch.Pose ToCore(Transform t)
        {
            return new Pinchmatch.Pose(ToCore(t.position), ToCore(t.rotation).Normalized);
        }

        public static Vector3 ToUnity(Vec3 v) { return new Vector3((float)v.X, (float)v.Y, (float)v.Z); }

        public static Quaternion ToUnity(Quat q) { return new Quaternion((float)q.X, (float)q.Y, (float)q.Z, (float)q.W); }

        public static void Apply(Transform t, Pinchmatch.Pose pose)
        {
            t.SetPositionAndRotation(ToUnity(pose.Position), ToUnity(pose.Rotation));
        }
    }
}
