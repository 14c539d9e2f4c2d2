// A stub of exactly the XR Hands (com.unity.xr.hands) members the components use, with the package's
// names and signatures (see UnityEngine.cs beside it).
namespace UnityEngine.XR.Hands
{
    public enum XRHandJointID
    {
        Invalid = 0, Wrist = 1, Palm = 2, ThumbMetacarpal = 3, ThumbProximal = 4, ThumbDistal = 5,
        ThumbTip = 6, IndexMetacarpal = 7, IndexProximal = 8, IndexIntermediate = 9, IndexDistal = 10,
        IndexTip = 11, MiddleMetacarpal = 12, MiddleProximal = 13, MiddleIntermediate = 14,
        MiddleDistal = 15, MiddleTip = 16,
    }

    public struct XRHandJoint
    {
        public bool TryGetPose(out Pose pose) { pose = default(Pose); return false; }
    }

    public struct XRHand
    {
        public bool isTracked { get { return false; } }
        public XRHandJoint GetJoint(XRHandJointID jointId) { return default(XRHandJoint); }
    }

    public class XRHandSubsystem : ISubsystem
    {
        public bool running { get { return false; } }
        public XRHand leftHand { get { return default(XRHand); } }
        public XRHand rightHand { get { return default(XRHand); } }
    }
}
