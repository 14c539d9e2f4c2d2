using System;
using System.Collections.Generic;
using System.IO;
using NUnit.Framework;
using Pinchmatch;

namespace Pinchmatch.Tests
{
    /// <summary>The result folder's reading, as the console entry does it (Tools~/Console runs the
    /// same calls).</summary>
    [TestFixture]
    public class ResultFolderTests
    {
        string folder;

        [SetUp]
        public void MakeFolder()
        {
            folder = Path.Combine(Path.GetTempPath(), "pinchmatch-unity-" + Guid.NewGuid().ToString("N"));
            Directory.CreateDirectory(folder);
        }

        [TearDown]
        public void RemoveFolder()
        {
            Directory.Delete(folder, true);
        }

        [Test]
        public void AResultIsReadFromItsFolder()
        {
            File.WriteAllText(Path.Combine(folder, "matches.json"),
                              Fixtures.Result(Fixtures.ZUp, Fixtures.Tripod, Quat.Identity, new Vec3(1, 2, 3)));
            var file = MatchesFile.Load(Path.Combine(folder, "matches.json"));
            Assert.AreEqual("tripod", file.GraspKind);
            Assert.AreEqual(3, file.Matches[0].Best.OnTangible.ContactsMm.Length);
            Assert.AreEqual("prop", file.Tangible("prop").Name);
            Assert.Throws<KeyNotFoundException>(() => file.Tangible("nothing"));
        }

        [Test]
        public void AMissingOrBrokenFileIsNamed()
        {
            string path = Path.Combine(folder, "matches.json");
            Assert.Throws<FileNotFoundException>(() => MatchesFile.Load(path));
            File.WriteAllText(path, "{\"schema\": \"pinchmatch.matches/1\", ");
            var e = Assert.Throws<JsonException>(() => MatchesFile.Load(path));
            StringAssert.Contains(path, e.Message);
            Assert.Throws<FileNotFoundException>(() => LevelFile.Load(Path.Combine(folder, "level.glb")));
        }

        [Test]
        public void ALevelIsReadFromItsGlb()
        {
            string path = Path.Combine(folder, "level.glb");
            File.WriteAllBytes(path, LevelTests.Glb(LevelTests.LevelJson()));
            Assert.AreEqual(2, LevelFile.Load(path).Matches.Count);
        }
    }
}
