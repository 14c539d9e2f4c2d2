// A stub of exactly the UnityEngine members the package's components use, with Unity's names and
// signatures, so that CI compiles the components without the editor: a typo or a member Unity does
// not have fails the build. Nothing here runs; the folder's "~" keeps Unity from compiling it.
using System;
using System.Collections.Generic;

namespace UnityEngine
{
    public class Object
    {
        public string name { get; set; }
        public static T Instantiate<T>(T original, Transform parent) where T : Object { throw new NotImplementedException(); }
    }

    public class Component : Object
    {
        public Transform transform { get { throw new NotImplementedException(); } }
        public GameObject gameObject { get { throw new NotImplementedException(); } }
    }

    public class Behaviour : Component
    {
        public bool enabled { get; set; }
    }

    public class MonoBehaviour : Behaviour { }

    public class Transform : Component
    {
        public Vector3 position { get; set; }
        public Quaternion rotation { get; set; }
        public void SetPositionAndRotation(Vector3 position, Quaternion rotation) { }
        public Vector3 TransformPoint(Vector3 position) { throw new NotImplementedException(); }
    }

    public sealed class GameObject : Object
    {
        public Transform transform { get { throw new NotImplementedException(); } }
        public void SetActive(bool value) { }
        public T AddComponent<T>() where T : Component { throw new NotImplementedException(); }
    }

    public class TextAsset : Object
    {
        public string text { get { throw new NotImplementedException(); } }
        public byte[] bytes { get { throw new NotImplementedException(); } }
    }

    public struct Vector3
    {
        public float x, y, z;
        public Vector3(float x, float y, float z) { this.x = x; this.y = y; this.z = z; }
        public static Vector3 zero { get { return new Vector3(0, 0, 0); } }
        public static Vector3 up { get { return new Vector3(0, 1, 0); } }
        public static Vector3 operator +(Vector3 a, Vector3 b) { return new Vector3(a.x + b.x, a.y + b.y, a.z + b.z); }
    }

    public struct Quaternion
    {
        public float x, y, z, w;
        public Quaternion(float x, float y, float z, float w) { this.x = x; this.y = y; this.z = z; this.w = w; }
        public static Quaternion LookRotation(Vector3 forward, Vector3 upwards) { throw new NotImplementedException(); }
    }

    public struct Pose
    {
        public Vector3 position;
        public Quaternion rotation;
    }

    public static class Debug
    {
        public static void Log(object message) { }
        public static void LogError(object message) { }
    }

    public static class Time
    {
        public static float time { get { throw new NotImplementedException(); } }
    }

    [AttributeUsage(AttributeTargets.Field, Inherited = true, AllowMultiple = false)]
    public class TooltipAttribute : Attribute
    {
        public TooltipAttribute(string tooltip) { }
    }

    public interface ISubsystem
    {
        bool running { get; }
    }

    public static class SubsystemManager
    {
        public static void GetSubsystems<T>(List<T> subsystems) where T : ISubsystem { }
    }
}
