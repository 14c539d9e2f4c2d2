// The tracked fingertips from XR Hands (XRHandSubsystem), in Unity's world: the joints' poses are
// relative to the XR Origin, so they are moved by its transform.
using System.Collections.Generic;
using UnityEngine;
using UnityEngine.XR.Hands;

namespace Pinchmatch.Unity
{
    public static class HandJoints
    {
        static readonly List<XRHandSubsystem> Found = new List<XRHandSubsystem>();

        static readonly XRHandJointID[] Tips = { XRHandJointID.ThumbTip, XRHandJointID.IndexTip, XRHandJointID.MiddleTip };

        /// <summary>The running hand subsystem, or null.</summary>
        public static XRHandSubsystem Subsystem()
        {
            Found.Clear();
            SubsystemManager.GetSubsystems(Found);
            foreach (var s in Found) if (s.running) return s;
            return null;
        }

        /// <summary>The hand's thumb, index (and middle, for <paramref name="count"/> 3) tips in
        /// the world, or null where the hand or a joint is not tracked.</summary>
        public static Vec3[] Fingertips(XRHand hand, Transform origin, int count)
        {
            if (!hand.isTracked) return null;
            var tips = new Vec3[count];
            for (int i = 0; i < count; i++)
            {
                UnityEngine.Pose pose;
                if (!hand.GetJoint(Tips[i]).TryGetPose(out pose)) return null;
                var p = origin != null ? origin.TransformPoint(pose.position) : pose.position;
                tips[i] = UnityConvert.ToCore(p);
            }
            return tips;
        }
    }
}
